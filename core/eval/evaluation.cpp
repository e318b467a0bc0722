#include "nirslam/eval/evaluation.hpp"

#include <algorithm>
#include <array>
#include <cstdio>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "nirslam/common/error.hpp"

namespace nirslam {

namespace fs = std::filesystem;

EvaluationResult evaluate(const Trajectory& estimate, const Trajectory& ground_truth, const EvaluationOptions& options) {
  const fs::path est_name = estimate.source.empty() ? fs::path("estimate") : estimate.source;
  if (options.align_first == 1 || options.align_first == 2)
    throw InputError(est_name, "align_first",
                     "aligning on the first " + std::to_string(options.align_first) +
                         " pair(s) is not possible: at least 3 are needed (0 aligns on all)");
  if (options.rpe_delta_frames == 0) throw InputError(est_name, "rpe_delta_frames", "must be at least 1");

  EvaluationResult result;
  result.association = associate(estimate, ground_truth, options.association);
  result.position_only = result.association.position_only;

  const std::vector<PosePair>& pairs = result.association.pairs;
  std::vector<Eigen::Vector3d> est_positions;
  est_positions.reserve(pairs.size());
  result.ground_truth_positions.reserve(pairs.size());
  result.timestamps_s.reserve(pairs.size());
  for (const PosePair& p : pairs) {
    est_positions.push_back(p.T_world_cam_estimate.translation());
    result.ground_truth_positions.push_back(p.T_world_cam_ground_truth.translation());
    result.timestamps_s.push_back(p.timestamp_s);
  }

  try {
    result.alignment = align_positions(est_positions, result.ground_truth_positions, options.alignment, options.align_first);
  } catch (const std::invalid_argument& e) {
    const std::size_t used = options.align_first == 0 ? pairs.size() : std::min(options.align_first, pairs.size());
    const std::string which = used < pairs.size() ? "on the first " + std::to_string(used) + " of " +
                                                        std::to_string(pairs.size()) + " matched pairs"
                                                  : "on the " + std::to_string(pairs.size()) + " matched pairs";
    throw InputError(est_name, "cannot align (" + to_string(options.alignment) + ") " + which + ": " + e.what() +
                                   "; use no alignment, or a stretch of trajectory that turns");
  }

  std::vector<SE3> est_aligned, gt_poses;
  est_aligned.reserve(pairs.size());
  gt_poses.reserve(pairs.size());
  result.estimate_positions_aligned.reserve(pairs.size());
  for (const PosePair& p : pairs) {
    est_aligned.push_back(result.alignment.transform.apply(p.T_world_cam_estimate));
    gt_poses.push_back(p.T_world_cam_ground_truth);
    result.estimate_positions_aligned.push_back(est_aligned.back().translation());
  }
  result.position_errors_m = position_errors(result.estimate_positions_aligned, result.ground_truth_positions);
  result.ate_m = summarize_errors(result.position_errors_m);

  const bool with_rotation = !result.position_only;
  result.rpe_per_frame = relative_error_per_frame(est_aligned, gt_poses, options.rpe_delta_frames, with_rotation);
  if (options.rpe_distance_m > 0.0)
    result.rpe_per_distance = relative_error_per_distance(est_aligned, gt_poses, options.rpe_distance_m, with_rotation);
  result.ground_truth_path_length_m = path_length(result.ground_truth_positions).back();
  return result;
}

namespace {

nlohmann::json to_json(const ErrorStatistics& s) {
  if (s.count == 0) return nullptr;
  return {{"count", s.count}, {"rmse", s.rmse}, {"mean", s.mean}, {"median", s.median},
          {"std", s.std},     {"min", s.min},   {"max", s.max}};
}

template <typename T>
nlohmann::json optional_json(const std::optional<T>& value) {
  return value ? nlohmann::json(*value) : nlohmann::json(nullptr);
}

// Four significant digits.
std::string format(double value) {
  std::array<char, 64> buffer{};
  std::snprintf(buffer.data(), buffer.size(), "%.4g", value);
  return buffer.data();
}

std::string alignment_title(AlignmentMode mode) {
  switch (mode) {
    case AlignmentMode::None: return "without alignment";
    case AlignmentMode::SE3: return "after SE(3) alignment";
    case AlignmentMode::Sim3: return "after Sim(3) alignment";
  }
  return "";
}

}  // namespace

std::string evaluation_to_json(const EvaluationResult& result, int indent) {
  const Association& a = result.association;
  const AlignmentResult& al = result.alignment;
  nlohmann::json rotation = nlohmann::json::array();
  for (int r = 0; r < 3; ++r)
    rotation.push_back({al.transform.rotation(r, 0), al.transform.rotation(r, 1), al.transform.rotation(r, 2)});
  const Eigen::Vector3d& t = al.transform.translation;

  nlohmann::json json = {
      {"position_only", result.position_only},
      {"association",
       {{"method", a.options.method == AssociationMethod::Nearest ? "nearest" : "interpolate"},
        {"max_dt_s", a.options.max_dt_s},
        {"time_offset_s", a.options.time_offset_s},
        {"estimate_poses", a.estimate_count},
        {"ground_truth_poses", a.ground_truth_count},
        {"pairs", a.pairs.size()},
        {"unmatched_inside_overlap", a.unmatched_inside_overlap},
        {"max_abs_dt_s", a.max_abs_dt_s}}},
      {"alignment",
       {{"mode", to_string(al.mode)},
        {"pairs_used", al.pairs_used},
        {"scale", al.transform.scale},
        {"rotation", rotation},
        {"translation_m", {t.x(), t.y(), t.z()}},
        {"sim3_scale", optional_json(al.sim3_scale)},
        {"scale_error_percent", optional_json(al.scale_error_percent())}}},
      {"ground_truth_path_length_m", result.ground_truth_path_length_m},
      {"ate_m", to_json(result.ate_m)},
      {"rpe_per_frame",
       {{"delta_frames", static_cast<std::size_t>(result.rpe_per_frame.delta)},
        {"translation_m", to_json(result.rpe_per_frame.translation_m)},
        {"rotation_deg", to_json(result.rpe_per_frame.rotation_deg)}}},
  };
  if (result.rpe_per_distance) {
    const RelativeError& d = *result.rpe_per_distance;
    json["rpe_per_distance"] = {{"distance_m", d.delta},
                                {"segments", d.translation_m.count},
                                {"translation_m", to_json(d.translation_m)},
                                {"translation_percent", to_json(d.translation_percent)},
                                {"rotation_deg", to_json(d.rotation_deg)},
                                {"rotation_deg_per_m", to_json(d.rotation_deg_per_m)}};
  } else {
    json["rpe_per_distance"] = nullptr;
  }
  return json.dump(indent);
}

std::string evaluation_headline(const EvaluationResult& result) {
  std::string text = "ATE RMSE " + format(result.ate_m.rmse) + " m " + alignment_title(result.alignment.mode);
  if (result.alignment.mode == AlignmentMode::Sim3) text += " (scale " + format(result.alignment.transform.scale) + ")";
  const std::string pairs = std::to_string(result.association.pairs.size()) + " pairs";
  if (result.alignment.mode != AlignmentMode::None && result.alignment.pairs_used < result.association.pairs.size())
    text += " on the first " + std::to_string(result.alignment.pairs_used) + " of " + pairs;
  else
    text += ", " + pairs;
  return text;
}

}  // namespace nirslam
