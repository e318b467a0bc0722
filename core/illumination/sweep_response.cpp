#include "nirslam/illumination/sweep_response.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "nirslam/photometric/exposure_sweep_calibration.hpp"

namespace nirslam {

const char* to_string(SweepResponse::State state) {
  switch (state) {
    case SweepResponse::State::Fitting: return "fitting";
    case SweepResponse::State::Done: return "done";
    case SweepResponse::State::Failed: return "failed";
  }
  return "unknown";
}

void SweepShots::clear() {
  shots_.clear();
  missing_exposure_ = 0;
  unusable_images_ = 0;
}

void SweepShots::add(double power_w, const Frame& frame) {
  const auto at_power = std::count_if(shots_.begin(), shots_.end(),
                                      [&](const SweepShot& shot) { return std::abs(shot.power_w - power_w) < 1e-3; });
  if (at_power >= kPerPower) return;
  if (frame.image.empty() || frame.image.channels() != 1 ||
      (frame.image.depth() != CV_8U && frame.image.depth() != CV_16U)) {
    ++unusable_images_;
    return;
  }
  if (!frame.exposure_ms || !(*frame.exposure_ms > 0.0)) {
    ++missing_exposure_;
    return;
  }
  SweepShot shot{power_w, *frame.exposure_ms * frame.gain.value_or(1.0), {}};
  if (frame.image.depth() == CV_16U)
    frame.image.convertTo(shot.grey, CV_8U, 1.0 / 257.0);
  else
    shot.grey = frame.image.clone();  // the source may reuse its buffer
  shots_.push_back(std::move(shot));
}

SweepResponse fit_sweep_response(const std::vector<SweepShot>& shots) {
  SweepResponse out;
  out.state = SweepResponse::State::Failed;
  std::vector<double> lit;
  for (const SweepShot& shot : shots)
    if (shot.power_w > 0.0 &&
        std::none_of(lit.begin(), lit.end(), [&](double p) { return std::abs(p - shot.power_w) < 1e-3; }))
      lit.push_back(shot.power_w);
  std::sort(lit.begin(), lit.end());
  if (lit.size() < 3) {
    out.reason = fmt::format("{} lamp powers above 0 W with a reported exposure; the response needs 3 or more", lit.size());
    return out;
  }
  std::vector<cv::Mat> images;
  std::vector<PowerSweepFrame> frames;
  for (const SweepShot& shot : shots) {
    images.push_back(shot.grey);
    frames.push_back({shot.power_w, shot.exposure});
  }
  const ExposureSweepResult fit = calibrate_power_sweep(images, frames, true);
  out.residual_rms_grey = fit.residual_rms_grey;
  out.points = fit.point_count;
  if (!fit.ok) {
    out.reason = fit.reason;
    return out;
  }
  out.state = SweepResponse::State::Done;
  out.response = fit.response;
  out.images = static_cast<int>(std::count_if(fit.images.begin(), fit.images.end(),
                                              [](const ExposureSweepImage& image) { return image.used; }));
  out.powers_w = lit;
  out.ambient_share_at_weakest = fit.ambient_share_at_weakest;
  if (fit.weakest_image >= 0) out.weakest_power_w = shots[static_cast<std::size_t>(fit.weakest_image)].power_w;
  out.highest_grey = fit.highest_grey;
  out.exposure_factor = sweep_exposure_factor(fit);
  if (out.residual_rms_grey > kSweepResponseMaxResidualGrey)
    out.warning = fmt::format("residual {:.1f} grey levels: did the rig or the scene move, or the exposure not hold?",
                              out.residual_rms_grey);
  else
    out.warning = sweep_range_advice(fit);
  return out;
}

void write_sweep_response(const SweepResponse& response, const std::filesystem::path& folder) {
  std::filesystem::create_directories(folder);
  write_pcalib(folder / "pcalib.txt", response.response.inverse_table());
  const Eigen::Vector4d& c = response.response.coefficients();
  const nlohmann::json summary = {
      {"response_coefficients", {c[0], c[1], c[2], c[3]}},
      {"ambiguity_resolution", "illuminator power sweep (the lamp's radiance proportional to power x exposure x gain, "
                               "plus per point an ambient radiance proportional to exposure x gain)"},
      {"powers_w", response.powers_w},
      {"images", response.images},
      {"points", response.points},
      {"residual_rms_grey", response.residual_rms_grey},
      {"highest_grey", response.highest_grey},
      {"ambient_share_at_lowest_power", response.ambient_share_at_weakest},
      {"lowest_power_w", response.weakest_power_w},
      {"warning", response.warning}};
  const std::filesystem::path file = folder / "sweep_response.json";
  std::ofstream out(file);
  out << summary.dump(2) << "\n";
  out.flush();
  if (!out) throw std::runtime_error(file.string() + ": cannot write");
}

}  // namespace nirslam
