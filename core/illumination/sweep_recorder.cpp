#include "nirslam/illumination/sweep_recorder.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <type_traits>

#include <spdlog/fmt/fmt.h>

namespace nirslam {

const char* to_string(SweepStage stage) {
  switch (stage) {
    case SweepStage::Idle: return "idle";
    case SweepStage::AwaitingPower: return "awaiting power";
    case SweepStage::Capturing: return "capturing";
    case SweepStage::Complete: return "complete";
  }
  return "unknown";
}

std::optional<double> IlluminationStatus::requested_power_w() const {
  if (progress.stage != SweepStage::AwaitingPower || progress.step >= plan.powers_w.size()) return std::nullopt;
  return plan.powers_w[progress.step];
}

SweepRecorder::SweepRecorder(IlluminationConfig config) : config_(std::move(config)), plan_(config_.sweep) {
  if (config_.scenes.empty()) config_.scenes = default_illumination_config().scenes;
  config_.exposure.max_saturated_fraction = config_.advisor.max_saturated_fraction;
  recommend();
  publish();
}

SweepRecord& SweepRecorder::active() {
  const std::string& name = config_.scenes[scene_index_].name;
  auto it = sweeps_.find(name);
  if (it == sweeps_.end()) it = sweeps_.emplace(name, SweepRecord(name)).first;
  return it->second;
}

const SweepRecord& SweepRecorder::sweep(const std::string& scene) const {
  static const SweepRecord empty;
  const SceneType* type = find_scene(config_.scenes, scene);
  if (type == nullptr) return empty;
  const auto it = sweeps_.find(type->name);
  return it == sweeps_.end() ? empty : it->second;
}

void SweepRecorder::set_illuminator(const IlluminatorCapabilities& capabilities) {
  config_.illuminator = capabilities;
  recommend();
  publish();
}

void SweepRecorder::advance_step() {
  ++progress_.step;
  progress_.capturing_w.reset();
  progress_.stage = progress_.step < plan_.powers_w.size() ? SweepStage::AwaitingPower : SweepStage::Complete;
}

bool SweepRecorder::apply(const SweepCommand& command) {
  bool accepted = true;
  std::visit(
      [&](const auto& c) {
        using C = std::decay_t<decltype(c)>;
        if constexpr (std::is_same_v<C, sweep_command::SelectScene>) {
          const SceneType* scene = find_scene(config_.scenes, c.scene);
          if (scene == nullptr) {
            accepted = false;
            message_ = fmt::format("unknown scene '{}'", c.scene);
            return;
          }
          scene_index_ = static_cast<std::size_t>(scene - config_.scenes.data());
          progress_ = {};  // a sweep belongs to one scene: switching ends the wizard
          message_ = fmt::format("scene: {}", scene->label);
        } else if constexpr (std::is_same_v<C, sweep_command::Start>) {
          SweepPlan plan = config_.sweep;
          if (!c.powers_w.empty()) plan.powers_w = c.powers_w;
          if (c.frames_per_power > 0) plan.frames_per_power = c.frames_per_power;
          for (const double p : plan.powers_w) {
            if (!std::isfinite(p) || p < config_.illuminator.min_power_w || p > config_.illuminator.max_power_w) {
              accepted = false;
              message_ = fmt::format("sweep power {:g} W outside the illuminator's {:g}-{:g} W", p,
                                     config_.illuminator.min_power_w, config_.illuminator.max_power_w);
              return;
            }
          }
          plan_ = plan;
          active().clear();
          progress_ = {};
          progress_.stage = SweepStage::AwaitingPower;
          message_ = fmt::format("sweep of {} started: {} powers, {} frames each", config_.scenes[scene_index_].label,
                                 plan_.powers_w.size(), plan_.frames_per_power);
        } else if constexpr (std::is_same_v<C, sweep_command::Capture>) {
          if (!std::isfinite(c.power_w) || c.power_w < 0.0) {
            accepted = false;
            message_ = fmt::format("cannot capture at {:g} W", c.power_w);
            return;
          }
          // Capturing a power again replaces its earlier frames.
          SweepRecord& sweep = active();
          SweepRecord kept(sweep.scene());
          for (const SweepPoint& p : sweep.points())
            if (std::abs(p.power_w - c.power_w) > SweepRecord::kSamePowerW) kept.add_point(p);
          sweep = std::move(kept);
          if (progress_.stage == SweepStage::Idle || progress_.stage == SweepStage::Complete) {
            // A single power outside the wizard: afterwards the wizard stays where it was.
            progress_.step = plan_.powers_w.size();
          }
          progress_.stage = SweepStage::Capturing;
          progress_.capturing_w = c.power_w;
          progress_.settle_remaining = plan_.settle_frames;
          progress_.frames_captured = 0;
          progress_.frames_wanted = plan_.frames_per_power;
          progress_.frames_ignored = 0;
          message_ = fmt::format("capturing {} frames at {:g} W", plan_.frames_per_power, c.power_w);
        } else if constexpr (std::is_same_v<C, sweep_command::Skip>) {
          if (progress_.stage != SweepStage::AwaitingPower) {
            accepted = false;
            message_ = "nothing to skip";
            return;
          }
          message_ = fmt::format("skipped {:g} W", plan_.powers_w[progress_.step]);
          advance_step();
        } else if constexpr (std::is_same_v<C, sweep_command::Finish>) {
          if (progress_.stage == SweepStage::Idle) return;
          progress_.stage = SweepStage::Complete;
          progress_.capturing_w.reset();
          message_ = "sweep finished";
        } else if constexpr (std::is_same_v<C, sweep_command::Clear>) {
          active().clear();
          progress_ = {};
          message_ = "sweep cleared";
        } else if constexpr (std::is_same_v<C, sweep_command::SetSettings>) {
          const AdvisorSettings& s = c.settings;
          if (!(s.plateau_share > 0.0 && s.plateau_share < 1.0) ||
              !(s.max_saturated_fraction >= 0.0 && s.max_saturated_fraction <= 1.0) || s.min_sweep_points < 3) {
            accepted = false;
            message_ = "advisor settings: share must be in (0, 1), the clipping limit in [0, 1], at least 3 points";
            return;
          }
          config_.advisor = s;
          config_.exposure.max_saturated_fraction = s.max_saturated_fraction;
        }
      },
      command);
  recommend();
  publish();
  return accepted;
}

bool SweepRecorder::add_frame(const FrameMetrics& metrics, std::optional<double> power_w, bool power_from_frame) {
  last_captured_w_.reset();
  if (progress_.stage != SweepStage::Capturing || !progress_.capturing_w) return false;
  const double target = *progress_.capturing_w;
  // A frame from before the lamp changed (still in the camera's pipeline) does not count.
  if (power_w && std::abs(*power_w - target) > SweepRecord::kSamePowerW) {
    ++progress_.frames_ignored;
    publish();
    return true;
  }
  if (progress_.settle_remaining > 0 && !power_from_frame) {
    --progress_.settle_remaining;
    publish();
    return true;
  }
  progress_.settle_remaining = 0;
  active().add(target, metrics);
  last_captured_w_ = target;
  ++progress_.frames_captured;
  if (progress_.frames_captured >= progress_.frames_wanted) {
    message_ = fmt::format("{:g} W done ({} frames)", target, progress_.frames_captured);
    if (progress_.step < plan_.powers_w.size()) {
      advance_step();
    } else {
      progress_.stage = SweepStage::Complete;
      progress_.capturing_w.reset();
    }
    recommend();
  }
  publish();
  return true;
}

void SweepRecorder::recommend() {
  const SceneType& scene = config_.scenes[scene_index_];
  const auto it = sweeps_.find(scene.name);
  static const std::vector<SweepPoint> none;
  const std::vector<SweepPoint>& points = it == sweeps_.end() ? none : it->second.points();
  // A power still being captured is not a point yet.
  std::vector<SweepPoint> complete;
  for (const SweepPoint& p : points)
    if (!(progress_.stage == SweepStage::Capturing && progress_.capturing_w &&
          std::abs(p.power_w - *progress_.capturing_w) <= SweepRecord::kSamePowerW))
      complete.push_back(p);
  recommendation_ = advise(complete, &scene, config_.advisor, config_.illuminator);
}

void SweepRecorder::publish() {
  auto status = std::make_shared<IlluminationStatus>();
  status->revision = ++revision_;
  status->scenes = config_.scenes;
  status->scene_index = scene_index_;
  status->plan = plan_;
  status->progress = progress_;
  const auto it = sweeps_.find(config_.scenes[scene_index_].name);
  if (it != sweeps_.end()) status->points = it->second.points();
  status->recommendation = recommendation_;
  status->settings = config_.advisor;
  status->illuminator = config_.illuminator;
  status->message = message_;
  status_ = std::move(status);
}

}  // namespace nirslam
