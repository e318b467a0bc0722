#pragma once

// The power-sweep wizard's state and the sweeps it records, kept in core (the worker owns one and
// feeds it every frame); the UI shows the published IlluminationStatus and posts SweepCommands.
//
// A sweep of the active scene goes: Start (plan: powers and frames per power) -> for each power:
// the operator sets the lamp and confirms the power (Capture) -> after `settle_frames` the next
// `frames_per_power` frames taken at that power are averaged -> the next planned power is asked for
// -> Complete. The curve fit and the recommendation are renewed whenever a power is complete.
// Each scene type keeps its own sweep; the scene's prior stands until its sweep can replace it.

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "nirslam/config/illumination_config.hpp"
#include "nirslam/illumination/advisor.hpp"
#include "nirslam/illumination/sweep.hpp"
#include "nirslam/quality/frame_metrics.hpp"

namespace nirslam {

enum class SweepStage {
  Idle,           // no sweep under way (points of an earlier sweep may be shown)
  AwaitingPower,  // waiting for the operator to set the lamp to the next power and confirm
  Capturing,      // averaging frames at the confirmed power
  Complete,       // every planned power done (or the operator finished early)
};
const char* to_string(SweepStage stage);

struct SweepProgress {
  SweepStage stage = SweepStage::Idle;
  std::size_t step = 0;               // index in the plan of the power asked for (or being captured)
  std::optional<double> capturing_w{};  // the power being captured
  int settle_remaining = 0;           // frames still to skip before averaging
  int frames_captured = 0;            // at capturing_w
  int frames_wanted = 0;
  int frames_ignored = 0;             // frames that reported another power while capturing
};

// What the UI shows; immutable once published.
struct IlluminationStatus {
  std::uint64_t revision = 0;  // increases with every change
  std::vector<SceneType> scenes{};
  std::size_t scene_index = 0;  // into scenes: the active scene
  SweepPlan plan{};
  SweepProgress progress{};
  std::vector<SweepPoint> points{};  // the active scene's sweep, ascending power
  Recommendation recommendation{};   // from the sweep, else the prior
  AdvisorSettings settings{};
  IlluminatorCapabilities illuminator{};
  std::string message;             // the last thing the wizard has to say (a rejected command...)

  const SceneType* scene() const { return scene_index < scenes.size() ? &scenes[scene_index] : nullptr; }
  // The plan's power at the current step, when the wizard is waiting for one.
  std::optional<double> requested_power_w() const;
};

namespace sweep_command {
struct SelectScene { std::string scene; };                  // a name or alias of a configured scene
struct Start { std::vector<double> powers_w; int frames_per_power = 0; };  // empty / 0: the configured plan
struct Capture { double power_w = 0.0; };                     // the lamp is at power_w: average frames there
struct Skip {};                                               // skip the planned power asked for
struct Finish {};                                             // end the wizard, keep what was captured
struct Clear {};                                              // drop the active scene's sweep
struct SetSettings { AdvisorSettings settings; };
}  // namespace sweep_command

using SweepCommand = std::variant<sweep_command::SelectScene, sweep_command::Start, sweep_command::Capture,
                                  sweep_command::Skip, sweep_command::Finish, sweep_command::Clear,
                                  sweep_command::SetSettings>;

class SweepRecorder {
public:
  explicit SweepRecorder(IlluminationConfig config = default_illumination_config());

  // Applies an operator command. Invalid ones (unknown scene, negative power, a plan outside the
  // illuminator's range) change nothing but the status message; returns false for them.
  bool apply(const SweepCommand& command);

  // One processed frame and the power it was taken at (std::nullopt when unknown);
  // `power_from_frame` says whether the frame itself reported the power (then no settling is
  // needed). Returns true when the status changed.
  bool add_frame(const FrameMetrics& metrics, std::optional<double> power_w, bool power_from_frame);
  // The power the last add_frame counted its frame at; nothing when it was skipped (settling,
  // another power, no sweep capturing).
  std::optional<double> last_captured_w() const { return last_captured_w_; }

  // The lamp in use (manual entry or a source's own); the recommendation is held to its range.
  void set_illuminator(const IlluminatorCapabilities& capabilities);

  // The status as of the last change (the same pointer until something changes).
  std::shared_ptr<const IlluminationStatus> status() const { return status_; }
  const SweepRecord& sweep(const std::string& scene) const;
  const IlluminationConfig& config() const { return config_; }

private:
  SweepRecord& active();
  void advance_step();
  void recommend();
  void publish();

  IlluminationConfig config_;
  std::map<std::string, SweepRecord> sweeps_;  // by scene name
  std::size_t scene_index_ = 0;
  SweepPlan plan_;
  SweepProgress progress_;
  Recommendation recommendation_;
  std::string message_;
  std::optional<double> last_captured_w_;
  std::uint64_t revision_ = 0;
  std::shared_ptr<const IlluminationStatus> status_;
};

}  // namespace nirslam
