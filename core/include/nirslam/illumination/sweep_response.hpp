#pragma once

// The camera's response from the power-sweep wizard's own frames: issue 6's power-sweep route to
// the response (calibrate_power_sweep) in one step, for an operator who sweeps the lamp in the GUI
// with the rig standing still and the exposure locked. While the wizard captures at a power the
// worker keeps the first frames' grey images with their exposure (SweepShots); when the sweep is
// complete it fits the response off its frame loop (fit_sweep_response) and publishes the result;
// the operator can then hold it in the pipeline (write_sweep_response + given_holds: response).

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "nirslam/image/frame.hpp"
#include "nirslam/photometric/response_model.hpp"

namespace nirslam {

struct SweepShot {
  double power_w = 0.0;
  double exposure = 0.0;  // exposure time (ms) x gain
  cv::Mat grey;           // 8-bit (a 16-bit frame at grey / 257, the response's 0..255 scale)
};

class SweepShots {
public:
  // Frames kept per power: more only average noise, and each costs a full image.
  static constexpr int kPerPower = 2;

  void clear();
  // Keeps `frame` as taken at `power_w` unless kPerPower are kept there already. A frame without
  // a reported exposure cannot serve (the fit needs power x exposure); counted in missing_exposure().
  // Nor can one that is not an 8- or 16-bit grey image; counted in unusable_images().
  void add(double power_w, const Frame& frame);
  const std::vector<SweepShot>& shots() const { return shots_; }
  int missing_exposure() const { return missing_exposure_; }
  int unusable_images() const { return unusable_images_; }

private:
  std::vector<SweepShot> shots_;
  int missing_exposure_ = 0;
  int unusable_images_ = 0;
};

struct SweepResponse {
  enum class State { Fitting, Done, Failed };
  State state = State::Fitting;
  std::string reason;   // Failed: why (too few powers, no exposure reported, the fit's reason)
  std::string warning;  // Done, but doubtful: a residual that says the rig moved, images that stop short of the top
  ResponseModel response;
  double residual_rms_grey = 0.0;
  double highest_grey = 0.0;  // ExposureSweepResult::highest_grey: the top of the observed range
  double exposure_factor = 1.0;  // above 1: sweep again at this times the exposure (sweep_exposure_factor)
  int images = 0;  // fitted
  int points = 0;
  std::vector<double> powers_w;             // distinct powers fitted, ascending
  double ambient_share_at_weakest = 0.0;    // the ambient term's median share at the weakest power
  double weakest_power_w = 0.0;
  std::filesystem::path folder;  // where write_sweep_response put it (empty until then)
  bool held = false;             // the pipeline holds it (given_holds: response)
};
const char* to_string(SweepResponse::State state);

// Above this residual the images disagree with any response: the rig or the scene moved.
inline constexpr double kSweepResponseMaxResidualGrey = 2.0;

// The response from the shots (ambient term on, calibrate_power_sweep). Never throws for bad
// input: a Failed result says why.
SweepResponse fit_sweep_response(const std::vector<SweepShot>& shots);

// Writes DSO's pcalib.txt and sweep_response.json (powers, residual, ambient share) into `folder`
// (created), as `calibrate-sweep --out` does, so the folder serves as a given calibration holding
// the response. Throws std::runtime_error naming the file when it cannot be written.
void write_sweep_response(const SweepResponse& response, const std::filesystem::path& folder);

}  // namespace nirslam
