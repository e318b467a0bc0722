#pragma once

// Shared fixtures of the evaluation tests (tests/core/test_eval_*.cpp): a temporary folder per
// test, text files written at run time, and hand-made trajectories with known geometry.

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "nirslam/eval/alignment.hpp"
#include "nirslam/eval/evaluation.hpp"
#include "nirslam/eval/trajectory.hpp"

namespace nirslam::eval_testing {

namespace fs = std::filesystem;

const fs::path kEuroc = fs::path(NIRSLAM_SHARED_DATA_DIR) / "euroc_v1_01_micro";

class EvalFileTest : public ::testing::Test {
protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::temp_directory_path() / ("nirslam_" + std::string(info->test_suite_name()) + "_" + info->name() + "_" +
                                         std::to_string(std::random_device{}()));
    fs::create_directories(root_);
  }
  void TearDown() override { fs::remove_all(root_); }

  fs::path write(const std::string& name, const std::string& text) const {
    const fs::path file = root_ / name;
    std::ofstream out(file, std::ios::binary);
    out << text;
    EXPECT_TRUE(out.good()) << file;
    return file;
  }

  fs::path root_;
};

// A smooth closed loop of `count` poses over `duration_s` seconds, starting at t0: a 6 m x 4 m
// figure in x-y with 0.5 m of height change, camera looking along the path and rolling a little,
// so that no three positions are collinear and every rotation axis is exercised.
inline Trajectory loop_trajectory(std::size_t count, double duration_s, double t0 = 100.0) {
  Trajectory trajectory;
  for (std::size_t k = 0; k < count; ++k) {
    const double t = t0 + duration_s * static_cast<double>(k) / static_cast<double>(count);
    const double a = 2.0 * std::numbers::pi * (t - t0) / duration_s;
    const Eigen::Vector3d position(3.0 * std::cos(a), 2.0 * std::sin(2.0 * a), 0.5 * std::sin(a));
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(0.2 * std::sin(3.0 * a), Eigen::Vector3d::UnitX()) *
                               Eigen::AngleAxisd(0.1 * std::cos(a), Eigen::Vector3d::UnitY()))
                                  .toRotationMatrix();
    trajectory.poses.push_back({t, SE3(R, position)});
  }
  return trajectory;
}

inline Sim3Transform example_sim3() {
  Sim3Transform s;
  s.rotation = (Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(-0.3, Eigen::Vector3d::UnitX()) *
                Eigen::AngleAxisd(1.1, Eigen::Vector3d::UnitY()))
                   .toRotationMatrix();
  s.translation = Eigen::Vector3d(12.0, -4.5, 2.25);
  s.scale = 0.37;  // a monocular estimate in arbitrary units
  return s;
}

inline Trajectory transformed(const Trajectory& trajectory, const Sim3Transform& s) {
  Trajectory out = trajectory;
  for (TimedPose& p : out.poses) p.T_world_cam = s.apply(p.T_world_cam);
  return out;
}

// Options without designated initializers (GCC 12 warns about the members they leave out).
inline EvaluationOptions aligned_by(AlignmentMode mode, std::size_t align_first = 0) {
  EvaluationOptions options;
  options.alignment = mode;
  options.align_first = align_first;
  return options;
}

}  // namespace nirslam::eval_testing
