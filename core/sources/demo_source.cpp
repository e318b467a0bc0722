#include "nirslam/sources/demo_source.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

#include "nirslam/illumination/illuminator.hpp"

namespace nirslam {
namespace {

// The demo's virtual lamp: the operator's power changes the next frame's irradiance.
class DemoLamp final : public IlluminatorController {
public:
  explicit DemoLamp(double power_w) : power_w_(power_w) {
    capabilities_.min_power_w = 0.0;
    capabilities_.max_power_w = 150.0;
    capabilities_.reads_back = true;
    capabilities_.description = "the demo's virtual illuminator";
  }
  const IlluminatorCapabilities& capabilities() const override { return capabilities_; }
  double set_power(double watts) override { return power_w_ = capabilities_.settable(watts); }
  std::optional<double> current_power_w() const override { return power_w_; }
  double power_w() const { return power_w_; }

private:
  IlluminatorCapabilities capabilities_;
  double power_w_;
};

// Albedo texture with structure at several scales (blobs, blocks, edges), so entropy and later the
// odometry have something to hold on to. Built once, larger than the view, then warped per frame.
cv::Mat make_wall_texture(int width, int height, std::uint32_t seed) {
  std::mt19937 rng(seed);
  cv::RNG noise_rng(seed);
  cv::Mat albedo(height, width, CV_32FC1, cv::Scalar(0.0f));
  for (int octave = 0; octave < 5; ++octave) {
    const int cell = 256 >> octave;
    cv::Mat coarse(height / cell + 2, width / cell + 2, CV_32FC1);
    noise_rng.fill(coarse, cv::RNG::UNIFORM, 0.0, 1.0);
    cv::Mat fine;
    cv::resize(coarse, fine, cv::Size(coarse.cols * cell, coarse.rows * cell), 0, 0, cv::INTER_CUBIC);
    albedo += fine(cv::Rect(0, 0, width, height)) * (0.5 / (octave + 1));
  }
  std::uniform_int_distribution<int> px(0, width - 1), py(0, height - 1), size(8, 90);
  std::uniform_real_distribution<float> shade(-0.35f, 0.35f);
  for (int i = 0; i < 220; ++i) {
    const cv::Point corner(px(rng), py(rng));
    const cv::Rect block(corner, cv::Size(size(rng), size(rng)));
    cv::rectangle(albedo, block, cv::Scalar(shade(rng)), cv::FILLED, cv::LINE_AA);
  }
  cv::normalize(albedo, albedo, 0.08, 0.95, cv::NORM_MINMAX);
  return albedo;
}

// Irradiance from a light on the optical axis: beam narrowing towards the rim times lens
// vignetting, both radial in the image, as the design's halo factor H(x) = V(x) B(x).
cv::Mat make_halo(int width, int height) {
  cv::Mat halo(height, width, CV_32FC1);
  const double cx = 0.5 * (width - 1), cy = 0.5 * (height - 1);
  const double half_diagonal = std::hypot(cx, cy);
  for (int y = 0; y < height; ++y) {
    float* row = halo.ptr<float>(y);
    for (int x = 0; x < width; ++x) {
      const double r = std::hypot(x - cx, y - cy) / half_diagonal;
      const double r2 = r * r;
      const double vignette = 1.0 - 0.3 * r2 - 0.15 * r2 * r2;
      const double beam = std::exp(-1.2 * r2);
      row[x] = static_cast<float>(vignette * beam);
    }
  }
  return halo;
}

class DemoSource final : public Source {
public:
  explicit DemoSource(const DemoOptions& options) : options_(options) {
    if (options.width < 64 || options.height < 48)
      throw std::invalid_argument("demo source: image size must be at least 64x48");
    if (options.fps <= 0.0) throw std::invalid_argument("demo source: fps must be positive");
    if (!(options.illuminator_power_w >= 0.0 && options.illuminator_power_w <= 150.0))
      throw std::invalid_argument("demo source: illuminator power must be within 0..150 W");
    lamp_ = std::make_shared<DemoLamp>(options.illuminator_power_w);
    info_.kind = "demo";
    info_.description = "built-in demo: textured wall under a co-located NIR illuminator";
    if (options.frame_count > 0) info_.frame_count = static_cast<std::size_t>(options.frame_count);
    info_.nominal_fps = options.fps;
    info_.reports_lamp_power = options.illuminator_power_w > 0.0;
    wall_ = make_wall_texture(options.width * 2, options.height * 2, options.seed);
    halo_ = make_halo(options.width, options.height);
    noise_.create(options.height, options.width, CV_32FC1);
    rewind();
  }

  const SourceInfo& info() const override { return info_; }
  std::shared_ptr<IlluminatorController> illuminator() const override { return lamp_; }

  std::optional<Frame> next() override {
    if (options_.frame_count > 0 && index_ >= options_.frame_count) return std::nullopt;
    const double t = static_cast<double>(index_) / options_.fps;

    // A slow figure-of-eight drift with a gentle roll, as a hand-held rig would move.
    const double angle_deg = 8.0 * std::sin(0.35 * t);
    const double scale = 1.0 + 0.12 * std::sin(0.21 * t);
    const cv::Point2f centre(static_cast<float>(wall_.cols * 0.5 + 0.22 * wall_.cols * std::sin(0.3 * t)),
                             static_cast<float>(wall_.rows * 0.5 + 0.18 * wall_.rows * std::sin(0.6 * t)));
    cv::Mat warp = cv::getRotationMatrix2D(centre, angle_deg, scale);
    warp.at<double>(0, 2) += options_.width * 0.5 - centre.x;
    warp.at<double>(1, 2) += options_.height * 0.5 - centre.y;
    cv::warpAffine(wall_, albedo_view_, warp, cv::Size(options_.width, options_.height),
                   cv::INTER_LINEAR, cv::BORDER_REFLECT);

    // Irradiance proportional to power; a gamma-like response maps it to grey values. At 50 W and
    // 10 ms the centre of a bright patch is near the top of the range, as in the paper's rooms.
    const double power_w = lamp_->power_w();
    const double gain = power_w / 50.0 * options_.exposure_ms / 10.0;
    cv::multiply(albedo_view_, halo_, radiance_, gain);
    noise_rng_.fill(noise_, cv::RNG::NORMAL, 0.0, 0.008);
    radiance_ += noise_;
    cv::max(radiance_, 0.0, radiance_);
    cv::pow(radiance_, 1.0 / 2.2, radiance_);

    Frame frame;
    radiance_.convertTo(frame.image, CV_8UC1, 255.0);
    frame.bit_depth = 8;
    frame.timestamp_s = t;
    frame.index = index_;
    frame.exposure_ms = options_.exposure_ms;
    frame.gain = 1.0;
    frame.illuminator_power_w = power_w;
    frame.name = "demo/" + std::to_string(index_);
    ++index_;
    return frame;
  }

  void rewind() override {
    index_ = 0;
    noise_rng_ = cv::RNG(options_.seed);
  }

private:
  DemoOptions options_;
  SourceInfo info_;
  std::shared_ptr<DemoLamp> lamp_;
  cv::Mat wall_, halo_;
  cv::Mat albedo_view_, radiance_;
  cv::Mat noise_;
  cv::RNG noise_rng_;
  std::int64_t index_ = 0;
};

}  // namespace

std::unique_ptr<Source> make_demo_source(const DemoOptions& options) {
  return std::make_unique<DemoSource>(options);
}

}  // namespace nirslam
