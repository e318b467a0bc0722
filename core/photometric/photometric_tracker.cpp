#include "nirslam/photometric/photometric_tracker.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <tuple>
#include <utility>

#include <Eigen/Cholesky>
#include <opencv2/imgproc.hpp>

namespace nirslam {

namespace {

// Whether a square of half-size `radius` around p can be sampled bilinearly.
inline bool fits(const cv::Mat& image, const Eigen::Vector2d& p, int radius) {
  return std::isfinite(p.x()) && std::isfinite(p.y()) && p.x() - radius >= 0.0 && p.y() - radius >= 0.0 &&
         p.x() + radius < image.cols - 1 && p.y() + radius < image.rows - 1;
}

// Normalised cross-correlation of two patches (1: equal up to an affine brightness change).
double normalised_cross_correlation(const PatchSamples& a, const PatchSamples& b) {
  const Eigen::ArrayXf da = a.array() - a.mean();
  const Eigen::ArrayXf db = b.array() - b.mean();
  const double denominator = std::sqrt(static_cast<double>(da.square().sum()) * static_cast<double>(db.square().sum()));
  return denominator > 0.0 ? static_cast<double>((da * db).sum()) / denominator : 0.0;
}

// The brightness change (a, b) that gives `current` the mean and contrast of `reference` scaled:
// current ~ a reference + b. std::nullopt for a flat reference.
std::optional<std::pair<double, double>> matching_brightness(const PatchSamples& reference, const PatchSamples& current) {
  const double mean0 = reference.mean();
  const double mean1 = current.mean();
  const double sd0 = std::sqrt((reference.array() - static_cast<float>(mean0)).square().mean());
  const double sd1 = std::sqrt((current.array() - static_cast<float>(mean1)).square().mean());
  if (!(sd0 > 1e-6)) return std::nullopt;
  return std::pair{sd1 / sd0, mean1 - sd1 / sd0 * mean0};
}

constexpr int kTemplateSide = kPatchSide + 2;  // one extra pixel each side for the gradient
using TemplateSamples = Eigen::Matrix<float, kTemplateSide, kTemplateSide, Eigen::RowMajor>;

}  // namespace

std::vector<cv::Mat> build_intensity_pyramid(const cv::Mat& image, int bit_depth, int levels) {
  if (image.empty() || image.channels() != 1) throw std::invalid_argument("intensity pyramid: need a grey image");
  std::vector<cv::Mat> pyramid(static_cast<std::size_t>(std::max(levels, 1)));
  image.convertTo(pyramid[0], CV_32F, 1.0 / static_cast<double>((1u << bit_depth) - 1u));
  for (std::size_t l = 1; l < pyramid.size(); ++l) cv::pyrDown(pyramid[l - 1], pyramid[l]);
  return pyramid;
}

bool sample_patch(const cv::Mat& image, const Eigen::Vector2d& position, PatchSamples& samples) {
  if (!fits(image, position, kPatchRadius)) return false;
  for (int i = 0; i < kPatchSide; ++i)
    for (int j = 0; j < kPatchSide; ++j)
      samples[i * kPatchSide + j] =
          bilinear_sample(image, position.x() + (j - kPatchRadius), position.y() + (i - kPatchRadius));
  return true;
}

double frame_pair_gain(const std::vector<cv::Mat>& a, const std::vector<cv::Mat>& b) {
  if (a.empty() || b.empty()) return 1.0;
  const double mean_a = cv::mean(a.back())[0];
  const double mean_b = cv::mean(b.back())[0];
  return mean_a > 0.0 && mean_b > 0.0 ? mean_b / mean_a : 1.0;
}

double corner_isotropy(const std::vector<cv::Mat>& pyramid, const Eigen::Vector2d& position) {
  double isotropy = 1.0;
  for (std::size_t level = 0; level < pyramid.size(); ++level) {
    const cv::Mat& image = pyramid[level];
    const Eigen::Vector2d p = position / static_cast<double>(1 << level);
    if (!fits(image, p, kPatchRadius + 1)) {
      if (level == 0) return 0.0;
      break;  // coarser levels do not fit either; the tracker skips them or drops the track there
    }
    Eigen::Matrix2d structure = Eigen::Matrix2d::Zero();
    for (int i = -kPatchRadius; i <= kPatchRadius; ++i)
      for (int j = -kPatchRadius; j <= kPatchRadius; ++j) {
        const double x = p.x() + j, y = p.y() + i;
        const Eigen::Vector2d gradient(0.5 * (bilinear_sample(image, x + 1.0, y) - bilinear_sample(image, x - 1.0, y)),
                                       0.5 * (bilinear_sample(image, x, y + 1.0) - bilinear_sample(image, x, y - 1.0)));
        structure += gradient * gradient.transpose();
      }
    const double half_trace = 0.5 * structure.trace();
    const double spread = std::sqrt(std::max(half_trace * half_trace - structure.determinant(), 0.0));
    if (!(half_trace + spread > 0.0)) return 0.0;
    isotropy = std::min(isotropy, (half_trace - spread) / (half_trace + spread));
  }
  return isotropy;
}

std::optional<PatchTrack> track_patch(const std::vector<cv::Mat>& a, const std::vector<cv::Mat>& b,
                                      const Eigen::Vector2d& from, const Eigen::Vector2d& guess,
                                      const PhotometricTrackerOptions& options, std::optional<double> pair_gain) {
  const int levels = static_cast<int>(std::min(a.size(), b.size()));
  if (levels == 0) return std::nullopt;
  // pyrDown keeps every second pixel, so level l sees full-resolution position x at x / 2^l.
  Eigen::Vector2d p1 = guess / static_cast<double>(1 << (levels - 1));
  PatchTrack result;
  TemplateSamples templ;
  PatchSamples t, tx, ty, current;
  for (int level = levels - 1; level >= 0; --level) {
    const double scale = 1.0 / static_cast<double>(1 << level);
    const Eigen::Vector2d p0 = from * scale;
    const cv::Mat& image0 = a[static_cast<std::size_t>(level)];
    const cv::Mat& image1 = b[static_cast<std::size_t>(level)];
    if (!fits(image0, p0, kPatchRadius + 1) || !fits(image1, p1, kPatchRadius)) {
      if (level == 0 || !options.skip_coarse_levels_at_border) return std::nullopt;
      p1 *= 2.0;
      continue;
    }
    for (int i = 0; i < kTemplateSide; ++i)
      for (int j = 0; j < kTemplateSide; ++j)
        templ(i, j) = bilinear_sample(image0, p0.x() + (j - kPatchRadius - 1), p0.y() + (i - kPatchRadius - 1));
    // Template and its central-difference gradient, fixed for the level (inverse-compositional
    // style: the Jacobian does not need the warped image's gradient).
    Eigen::Matrix2d structure = Eigen::Matrix2d::Zero();
    for (int i = 0; i < kPatchSide; ++i)
      for (int j = 0; j < kPatchSide; ++j) {
        const int k = i * kPatchSide + j;
        t[k] = templ(i + 1, j + 1);
        tx[k] = 0.5f * (templ(i + 1, j + 2) - templ(i + 1, j));
        ty[k] = 0.5f * (templ(i + 2, j + 1) - templ(i, j + 1));
        const Eigen::Vector2d gradient(static_cast<double>(tx[k]), static_cast<double>(ty[k]));
        structure += gradient * gradient.transpose();
      }
    if (level == 0) {
      // Smaller eigenvalue of the mean structure tensor, relative to the patch brightness so a
      // dark (short exposure) frame is judged as a bright one: a flat patch gives no position.
      structure /= static_cast<double>(kPatchPixels);
      const double mean = std::max(static_cast<double>(t.mean()), 1e-3);
      const double tr = structure.trace();
      const double det = structure(0, 0) * structure(1, 1) - structure(0, 1) * structure(1, 0);
      const double lambda_min = 0.5 * (tr - std::sqrt(std::max(tr * tr - 4.0 * det, 0.0)));
      if (!(lambda_min / (mean * mean) >= options.min_structure)) return std::nullopt;
    }

    if (!sample_patch(image1, p1, current)) return std::nullopt;
    // Closed-form (a, b) at the start position: matching mean and contrast, so the first
    // position steps are taken with the brightness change already roughly right.
    const auto matched = matching_brightness(t, current);
    if (!matched) return std::nullopt;
    double gain = pair_gain ? *pair_gain : matched->first;
    double bias = pair_gain ? 0.0 : matched->second;

    for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
      if (iteration > 0 && !sample_patch(image1, p1, current)) return std::nullopt;
      // r = I_t(p1 + x) - a T(x) - b;  dr/d(d) ~ a grad T, dr/da = -T, dr/db = -1.
      Eigen::Matrix4d H = Eigen::Matrix4d::Zero();
      Eigen::Vector4d g = Eigen::Vector4d::Zero();
      double squared = 0.0;
      for (int k = 0; k < kPatchPixels; ++k) {
        const double r = current[k] - gain * t[k] - bias;
        const Eigen::Vector4d J(gain * tx[k], gain * ty[k], -t[k], -1.0);
        H.noalias() += J * J.transpose();
        g += J * r;
        squared += r * r;
      }
      result.residual_rms = std::sqrt(squared / kPatchPixels);
      Eigen::Vector4d step = Eigen::Vector4d::Zero();
      if (pair_gain) step.head<2>() = -H.topLeftCorner<2, 2>().ldlt().solve(g.head<2>());
      else step = -H.ldlt().solve(g);  // with a pair gain, gain and bias stay where they are
      if (!step.allFinite()) return std::nullopt;
      p1 += step.head<2>();
      gain += step[2];
      bias += step[3];
      if (step.head<2>().norm() < options.convergence_px) break;
    }
    result.brightness_gain = gain;
    result.brightness_bias = bias;
    if (level > 0) p1 *= 2.0;
  }
  result.position = p1;
  // The residual of the final position, for the outlier test.
  if (!sample_patch(b[0], p1, current)) return std::nullopt;
  // t still holds the full-resolution template (level 0 is processed last).
  result.residual_rms = std::sqrt(
      (current.array() - static_cast<float>(result.brightness_gain) * t.array() -
       static_cast<float>(result.brightness_bias)).square().mean());
  if (!(result.brightness_gain >= options.min_brightness_gain && result.brightness_gain <= options.max_brightness_gain))
    return std::nullopt;
  return result;
}

std::optional<AffinePatchAlignment> align_patch_affine(const cv::Mat& image, const PatchSamples& reference,
                                                       const Eigen::Vector2d& position, const Eigen::Matrix2d& warp,
                                                       const PhotometricTrackerOptions& options) {
  using Vector8d = Eigen::Matrix<double, 8, 1>;
  using Matrix8d = Eigen::Matrix<double, 8, 8>;
  AffinePatchAlignment out;
  out.position = position;
  out.warp = warp;
  // The warped patch and one pixel around it for the central differences.
  const auto inside = [&](const Eigen::Vector2d& c, const Eigen::Matrix2d& W) {
    const double reach = kPatchRadius * (W.cwiseAbs().rowwise().sum().maxCoeff()) + 1.0;
    return std::isfinite(reach) && c.allFinite() && c.x() - reach >= 0.0 && c.y() - reach >= 0.0 &&
           c.x() + reach < image.cols - 1 && c.y() + reach < image.rows - 1;
  };
  if (!inside(out.position, out.warp)) return std::nullopt;
  PatchSamples current;
  const auto sample_warped = [&] {  // the patch under the current position and warp
    for (int i = 0; i < kPatchSide; ++i)
      for (int j = 0; j < kPatchSide; ++j) {
        const Eigen::Vector2d w = out.position + out.warp * Eigen::Vector2d(j - kPatchRadius, i - kPatchRadius);
        current[i * kPatchSide + j] = bilinear_sample(image, w.x(), w.y());
      }
  };
  sample_warped();  // (a, b) matching mean and contrast at the start
  const auto matched = matching_brightness(reference, current);
  if (!matched) return std::nullopt;
  std::tie(out.gain, out.bias) = *matched;
  for (int iteration = 0; iteration < 2 * options.max_iterations; ++iteration) {
    // r = I(c + W o) - a T(o) - b; dr/dc = grad I, dr/dW_rs = (grad I)_r o_s, dr/da = -T, dr/db = -1.
    Matrix8d H = Matrix8d::Zero();
    Vector8d g = Vector8d::Zero();
    for (int i = 0; i < kPatchSide; ++i)
      for (int j = 0; j < kPatchSide; ++j) {
        const double ox = j - kPatchRadius, oy = i - kPatchRadius;
        const Eigen::Vector2d w = out.position + out.warp * Eigen::Vector2d(ox, oy);
        const double I = bilinear_sample(image, w.x(), w.y());
        const double Ix = 0.5 * (bilinear_sample(image, w.x() + 1.0, w.y()) - bilinear_sample(image, w.x() - 1.0, w.y()));
        const double Iy = 0.5 * (bilinear_sample(image, w.x(), w.y() + 1.0) - bilinear_sample(image, w.x(), w.y() - 1.0));
        const double T = reference[i * kPatchSide + j];
        const double r = I - out.gain * T - out.bias;
        Vector8d J;
        J << Ix, Iy, Ix * ox, Ix * oy, Iy * ox, Iy * oy, -T, -1.0;
        H.noalias() += J * J.transpose();
        g += J * r;
      }
    const Vector8d step = -H.ldlt().solve(g);
    if (!step.allFinite()) return std::nullopt;
    out.position += step.head<2>();
    out.warp(0, 0) += step[2];
    out.warp(0, 1) += step[3];
    out.warp(1, 0) += step[4];
    out.warp(1, 1) += step[5];
    out.gain += step[6];
    out.bias += step[7];
    if (!inside(out.position, out.warp)) return std::nullopt;
    if (step.head<2>().norm() < options.convergence_px && step.segment<4>(2).norm() * kPatchRadius < options.convergence_px) break;
  }
  sample_warped();  // the residual at the final values
  double squared = 0.0;
  for (int k = 0; k < kPatchPixels; ++k) {
    const double r = current[k] - out.gain * reference[k] - out.bias;
    squared += r * r;
  }
  out.residual_rms = std::sqrt(squared / kPatchPixels);
  if (!(out.gain >= options.min_brightness_gain && out.gain <= options.max_brightness_gain)) return std::nullopt;
  return out;
}

PhotometricTracker::PhotometricTracker(PhotometricTrackerOptions options)
    : options_(options), deformation_(options_.deformation) {
  if (options_.pyramid_levels < 1 || options_.max_tracks < 1 || options_.min_tracks < 0 || options_.grid_cols < 1 ||
      options_.grid_rows < 1)
    throw std::invalid_argument("photometric tracker: bad options");
}

void PhotometricTracker::reset() {
  previous_pyramid_.clear();
  current_ = {};
  deformation_.reset();
}

const TrackedFrame& PhotometricTracker::process(const Frame& frame, const cv::Mat& detection_allowed) {
  validate_frame(frame, "photometric tracker frame");
  if (!detection_allowed.empty() && (detection_allowed.type() != CV_8UC1 || detection_allowed.size() != frame.image.size()))
    throw std::invalid_argument("photometric tracker: the detection mask must be CV_8UC1 of the frame's size");
  std::vector<cv::Mat> pyramid = build_intensity_pyramid(frame.image, frame.bit_depth, options_.pyramid_levels);

  TrackedFrame next;
  next.frame_index = frame.index;
  next.width = frame.width();
  next.height = frame.height();
  next.exposure_ms = frame.exposure_ms;
  next.gain = frame.gain;

  // Black and saturated fractions on every second pixel of every second row: plenty for a
  // fraction, a quarter of the cost.
  {
    std::int64_t black = 0, saturated = 0, total = 0;
    const float black_level = static_cast<float>(options_.black_level);
    const float saturation_level = static_cast<float>(options_.saturation_level);
    for (int y = 0; y < pyramid[0].rows; y += 2) {
      const float* row = pyramid[0].ptr<float>(y);
      for (int x = 0; x < pyramid[0].cols; x += 2) {
        black += row[x] <= black_level;
        saturated += row[x] >= saturation_level;
        ++total;
      }
    }
    next.black_fraction = static_cast<double>(black) / static_cast<double>(std::max<std::int64_t>(total, 1));
    next.saturated_fraction = static_cast<double>(saturated) / static_cast<double>(std::max<std::int64_t>(total, 1));
  }

  if (!previous_pyramid_.empty() && previous_pyramid_[0].size() == pyramid[0].size()) {
    next.tracks.reserve(current_.tracks.size() + static_cast<std::size_t>(options_.max_tracks));
    const std::optional<double> pair_gain =
        options_.frame_pair_gain ? std::optional<double>(frame_pair_gain(previous_pyramid_, pyramid)) : std::nullopt;
    // Each track reads only the two pyramids and its own state: followed on two threads into
    // their slots, then kept in the same order as one thread would.
    const auto follow = [&](const TrackObservation& old, int TrackEnds::*& end) -> std::optional<TrackObservation> {
      const auto forward = track_patch(previous_pyramid_, pyramid, old.position, old.position, options_, pair_gain);
      end = &TrackEnds::not_found;
      if (!forward) return std::nullopt;
      end = &TrackEnds::residual;
      if (forward->residual_rms > options_.max_residual_rms) return std::nullopt;
      const auto backward = track_patch(pyramid, previous_pyramid_, forward->position, old.position, options_,
                                        pair_gain ? std::optional<double>(1.0 / *pair_gain) : std::nullopt);
      end = &TrackEnds::forward_backward;
      if (!backward || (backward->position - old.position).norm() > options_.max_forward_backward_px)
        return std::nullopt;
      end = &TrackEnds::reference;
      TrackObservation observation;
      observation.id = old.id;
      observation.position = forward->position;
      observation.age = old.age + 1;
      observation.brightness_gain = forward->brightness_gain;
      observation.reference = old.reference;
      observation.surface = old.surface;
      observation.reference_warp = old.reference_warp;
      bool new_surface = false;
      if (options_.align_reference_affine) {
        const auto aligned = align_patch_affine(pyramid[0], old.reference, forward->position, old.reference_warp, options_);
        const double area = aligned ? aligned->warp.determinant() : 0.0;
        if (aligned && (aligned->position - forward->position).norm() <= options_.max_reference_shift_px &&
            aligned->residual_rms <= options_.max_residual_rms && area >= 1.0 / options_.max_area_change &&
            area <= options_.max_area_change) {
          observation.position = aligned->position;
          observation.reference_warp = aligned->warp;
        } else {
          // The first patch no longer models this one (a glossy reflection, an occlusion, too much
          // deformation) while the step itself passed its checks: the track goes on from here as a
          // new surface, its patch now the first one.
          observation.reference_warp.setIdentity();
          observation.surface = old.surface + 1;
          new_surface = true;
        }
        observation.deformation = observation.reference_warp;
      }
      if (!sample_patch(pyramid[0], observation.position, observation.samples)) return std::nullopt;
      if (new_surface) observation.reference = observation.samples;
      if (options_.min_reference_ncc > 0.0 &&
          normalised_cross_correlation(observation.samples, observation.reference) < options_.min_reference_ncc)
        return std::nullopt;
      return observation;
    };
    const std::size_t count = current_.tracks.size();
    followed_.assign(count, std::nullopt);
    ends_.assign(count, &TrackEnds::not_found);
    split_in_two(*helper_, count, count / 2, 64, [&](std::size_t begin, std::size_t end, int) {
      for (std::size_t i = begin; i < end; ++i) followed_[i] = follow(current_.tracks[i], ends_[i]);
    });
    for (std::size_t i = 0; i < count; ++i) {
      if (followed_[i]) next.tracks.push_back(std::move(*followed_[i]));
      else ++(next.ended.*ends_[i]);
    }
  }
  next.intensity = pyramid[0];
  current_ = std::move(next);
  if (static_cast<int>(current_.tracks.size()) < options_.min_tracks) detect(pyramid, detection_allowed);
  if (options_.align_reference_affine) current_.deformation_estimated = true;  // each track's own warp
  else if (options_.estimate_deformation) deformation_.update(current_);
  previous_pyramid_ = std::move(pyramid);
  return current_;
}

void PhotometricTracker::detect(const std::vector<cv::Mat>& pyramid, const cv::Mat& allowed) {
  const cv::Mat& image = pyramid[0];
  const int margin = kPatchRadius + 2;
  if (image.cols <= 2 * margin || image.rows <= 2 * margin) return;
  detection_mask_.create(image.size(), CV_8UC1);
  detection_mask_.setTo(0);
  detection_mask_(cv::Rect(margin, margin, image.cols - 2 * margin, image.rows - 2 * margin)).setTo(255);
  if (!allowed.empty()) cv::bitwise_and(detection_mask_, allowed, detection_mask_);  // 255 & v is v: nonzero stays nonzero
  const int cells = options_.grid_cols * options_.grid_rows;
  bucket_counts_.assign(static_cast<std::size_t>(cells), 0);
  const auto bucket = [&](const Eigen::Vector2d& p) {
    const int cx = std::clamp(static_cast<int>(p.x() * options_.grid_cols / image.cols), 0, options_.grid_cols - 1);
    const int cy = std::clamp(static_cast<int>(p.y() * options_.grid_rows / image.rows), 0, options_.grid_rows - 1);
    return static_cast<std::size_t>(cy * options_.grid_cols + cx);
  };
  const int keep_out = static_cast<int>(std::lround(options_.min_corner_distance_px));
  for (const TrackObservation& track : current_.tracks) {
    cv::circle(detection_mask_, cv::Point(static_cast<int>(track.position.x()), static_cast<int>(track.position.y())),
               keep_out, cv::Scalar(0), cv::FILLED);
    ++bucket_counts_[bucket(track.position)];
  }
  const int wanted = options_.max_tracks - static_cast<int>(current_.tracks.size());
  if (wanted <= 0) return;
  std::vector<cv::Point2f> corners;
  // Corner quality is relative to the strongest corner, so detection does not depend on exposure.
  cv::goodFeaturesToTrack(image, corners, 2 * wanted, options_.corner_quality, options_.min_corner_distance_px,
                          detection_mask_, 5);
  const int per_cell = (options_.max_tracks + cells - 1) / cells;
  for (const cv::Point2f& corner : corners) {
    if (static_cast<int>(current_.tracks.size()) >= options_.max_tracks) break;
    TrackObservation observation;
    observation.position = Eigen::Vector2d(corner.x, corner.y);
    int& count = bucket_counts_[bucket(observation.position)];
    if (count >= per_cell) continue;
    if (options_.min_corner_isotropy > 0.0 &&
        !(corner_isotropy(pyramid, observation.position) >= options_.min_corner_isotropy))
      continue;
    if (!sample_patch(image, observation.position, observation.samples)) continue;
    observation.reference = observation.samples;
    observation.id = next_id_++;
    ++count;
    current_.tracks.push_back(observation);
    ++current_.new_tracks;
  }
}

}  // namespace nirslam
