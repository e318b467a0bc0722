// evaluate() end to end from files: formats mixed (EuRoC CSV ground truth at 200 Hz, TUM estimate at
// 20 Hz), a position-only total-station ground truth, the JSON report, and bad input reaching
// evaluate (NaN, unsorted, no overlap, too few poses).

#include <cmath>
#include <random>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/test_eval_fixtures.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/eval/evaluation.hpp"
#include "text_contains.hpp"

namespace nirslam {
namespace {

using eval_testing::EvalFileTest;
using eval_testing::aligned_by;
using eval_testing::example_sim3;
using eval_testing::loop_trajectory;
using eval_testing::transformed;
namespace fs = std::filesystem;

using Evaluation = EvalFileTest;


std::string euroc_csv(const Trajectory& t) {
  std::ostringstream out;
  out << "#timestamp [ns], p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z []\n";
  out.precision(12);
  for (const TimedPose& p : t.poses) {
    const auto& q = p.T_world_cam.unit_quaternion();
    const auto& x = p.T_world_cam.translation();
    out << static_cast<long long>(std::llround(p.timestamp_s * 1e9)) << ',' << x.x() << ',' << x.y() << ',' << x.z()
        << ',' << q.w() << ',' << q.x() << ',' << q.y() << ',' << q.z() << '\n';
  }
  return out.str();
}

TEST_F(Evaluation, EurocGroundTruthAgainstA20HzTumEstimate) {
  const Trajectory gt = loop_trajectory(4000, 20.0, 1403715274.302142);  // 200 Hz
  Trajectory est;  // every tenth pose, 1 ms late, moved by a Sim(3) and noised by 1 cm
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.01 / std::sqrt(3.0));
  for (std::size_t k = 0; k < gt.size(); k += 10) {
    TimedPose p = gt.poses[k];
    p.timestamp_s += 0.001;
    p.T_world_cam = SE3(p.T_world_cam.unit_quaternion(),
                        p.T_world_cam.translation() + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
    est.poses.push_back(p);
  }
  est = transformed(est, example_sim3().inverse());
  const fs::path gt_file = write("data.csv", euroc_csv(gt));
  const fs::path est_file = root_ / "est.txt";
  write_tum(est_file, est);

  const EvaluationResult r = evaluate(read_trajectory(est_file), read_trajectory(gt_file));
  EXPECT_EQ(r.association.pairs.size(), 400u);
  EXPECT_NEAR(r.association.max_abs_dt_s, 0.001, 1e-6);
  EXPECT_NEAR(r.ate_m.rmse, 0.01, 0.0015);
  EXPECT_NEAR(r.alignment.transform.scale, 0.37, 0.005);
  EXPECT_FALSE(r.position_only);
  ASSERT_TRUE(r.rpe_per_distance.has_value());
  EXPECT_GT(r.rpe_per_distance->translation_m.count, 300u);
  EXPECT_GT(r.ground_truth_path_length_m, 20.0);
  EXPECT_EQ(r.estimate_positions_aligned.size(), 400u);
  EXPECT_EQ(r.timestamps_s.size(), 400u);

  const nlohmann::json json = nlohmann::json::parse(evaluation_to_json(r));
  EXPECT_EQ(json["association"]["pairs"], 400);
  EXPECT_EQ(json["association"]["method"], "nearest");
  EXPECT_EQ(json["alignment"]["mode"], "sim3");
  EXPECT_NEAR(json["ate_m"]["rmse"].get<double>(), r.ate_m.rmse, 1e-12);
  EXPECT_TRUE(json["ate_m"].contains("median"));
  EXPECT_TRUE(json["rpe_per_frame"]["rotation_deg"].is_object());
  EXPECT_NEAR(json["rpe_per_distance"]["distance_m"].get<double>(), 1.0, 0.0);
  EXPECT_TRUE(json["rpe_per_distance"]["translation_percent"].is_object());
  EXPECT_TRUE(contains(evaluation_headline(r), "after Sim(3) alignment (scale 0.37")) << evaluation_headline(r);
}

TEST_F(Evaluation, TotalStationGroundTruthUsesPositionsOnly) {
  const Trajectory truth = loop_trajectory(200, 20.0, 50.0);  // 10 Hz prism positions
  Trajectory ts = truth;
  ts.position_only = true;
  const fs::path gt_file = root_ / "ts60.txt";
  write_positions(gt_file, ts);
  const Trajectory gt = read_trajectory(gt_file);
  ASSERT_TRUE(gt.position_only);
  const Trajectory est = transformed(truth, example_sim3());
  const EvaluationResult r = evaluate(est, gt, aligned_by(AlignmentMode::Sim3));
  EXPECT_TRUE(r.position_only);
  EXPECT_NEAR(r.ate_m.rmse, 0.0, 1e-7);
  EXPECT_FALSE(r.rpe_per_frame.has_rotation);
  EXPECT_EQ(r.rpe_per_frame.rotation_deg.count, 0u);
  const nlohmann::json json = nlohmann::json::parse(evaluation_to_json(r));
  EXPECT_TRUE(json["position_only"].get<bool>());
  EXPECT_TRUE(json["rpe_per_frame"]["rotation_deg"].is_null());
}

TEST_F(Evaluation, BadInputIsAClearError) {
  const Trajectory gt = loop_trajectory(100, 10.0);
  // NaN and unsorted in memory: named by pose.
  Trajectory nan = gt;
  nan.source = "odometry run";
  nan.poses[42].timestamp_s = std::nan("");
  try {
    evaluate(nan, gt);
    FAIL() << "NaN accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), fs::path("odometry run"));
    EXPECT_EQ(e.field(), "pose 42");
  }
  Trajectory unsorted = gt;
  std::swap(unsorted.poses[10], unsorted.poses[11]);
  EXPECT_THROW(evaluate(gt, unsorted), InputError);

  // No overlap in time, from files.
  Trajectory later = gt;
  for (TimedPose& p : later.poses) p.timestamp_s += 1000.0;
  const fs::path est_file = root_ / "later.txt";
  write_tum(est_file, later);
  try {
    evaluate(read_trajectory(est_file), gt);
    FAIL() << "no overlap accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), est_file);
    EXPECT_TRUE(contains(e.what(), "no overlap in time")) << e.what();
  }

  // Too few poses: a two-line estimate.
  const fs::path two = write("two.txt", "100.0 0 0 0 0 0 0 1\n100.1 1 0 0 0 0 0 1\n");
  try {
    evaluate(read_trajectory(two), gt);
    FAIL() << "two poses accepted";
  } catch (const InputError& e) {
    EXPECT_TRUE(contains(e.what(), "only 2 pose(s) pair up")) << e.what();
  }
}

}  // namespace
}  // namespace nirslam
