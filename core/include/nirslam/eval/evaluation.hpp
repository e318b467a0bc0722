#pragma once

// One call from two trajectories to every figure: associate, align, ATE, RPE. `nirslam eval`
// prints it; `nirslam bench` calls evaluate() per sequence and variant on trajectories held in
// memory and builds its tables from EvaluationResult (ate_m.rmse is the paper's Table 2 figure).

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nirslam/eval/alignment.hpp"
#include "nirslam/eval/association.hpp"
#include "nirslam/eval/trajectory.hpp"
#include "nirslam/eval/trajectory_error.hpp"

namespace nirslam {

struct EvaluationOptions {
  AssociationOptions association;
  AlignmentMode alignment = AlignmentMode::Sim3;
  std::size_t align_first = 0;  // align on the first N pairs only (0: all pairs)
  std::size_t rpe_delta_frames = 1;
  double rpe_distance_m = 1.0;  // 0 or less: no per-distance RPE
};

struct EvaluationResult {
  Association association;
  AlignmentResult alignment;
  bool position_only = false;
  // Per pair, in the order of association.pairs: timestamps, aligned estimated positions, the
  // ground-truth positions and their distance (the per-pose ATE the heat map colours by).
  std::vector<double> timestamps_s;
  std::vector<Eigen::Vector3d> estimate_positions_aligned;
  std::vector<Eigen::Vector3d> ground_truth_positions;
  std::vector<double> position_errors_m;
  ErrorStatistics ate_m;
  RelativeError rpe_per_frame;
  std::optional<RelativeError> rpe_per_distance;  // absent when rpe_distance_m <= 0
  double ground_truth_path_length_m = 0.0;          // along the matched pairs
};

// Validates both trajectories (validate_trajectory), associates them and aligns. Errors
// (InputError, naming the estimate's or ground truth's source): invalid input, no overlap in time,
// too few pairs, positions that cannot fix the alignment (collinear, one point), align_first 1-2.
EvaluationResult evaluate(const Trajectory& estimate, const Trajectory& ground_truth,
                          const EvaluationOptions& options = {});

// The figures as JSON text (units in the key names: _m, _deg, _percent, _deg_per_m, _s).
std::string evaluation_to_json(const EvaluationResult& result, int indent = 2);

// "ATE RMSE 0.123 m after Sim(3) alignment (scale 0.981), 412 pairs": one line for titles and logs.
std::string evaluation_headline(const EvaluationResult& result);

}  // namespace nirslam
