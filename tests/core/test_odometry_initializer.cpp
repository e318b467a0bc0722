// The initialiser's hypotheses after its snap run on two threads (InitializerOptions::
// parallel_hypotheses): each is aligned on its own copy of the initialiser, so the result must be
// the same, to the last bit, as aligning them one after the other; with the translation-direction
// search on too (held-direction candidates, the joint refinement over the frames since the snap
// on both threads), which also hands the refined poses of those frames to the odometry.

#include <memory>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "nirslam/odometry/coarse_initializer.hpp"
#include "nirslam/odometry/image_pyramid.hpp"
#include "nirslam/sim/simulator.hpp"

namespace nirslam::odometry {
namespace {

void expect_parallel_equals_sequential(const InitializerOptions& options) {
  // The hand-held tunnel at 20 W (a bench sequence), at half size to keep the test short; the
  // parallax threshold is for a 640-wide image, so the snap comes as at full size.
  SimulatorOptions o;
  o.scene = sim::SceneKind::Tunnel;
  o.powers_w = {20.0};
  o.frames = 30;
  o.width = 320;
  o.height = 240;
  o.supersampling = 1;
  Simulator simulator(o);
  const auto camera = make_sim_camera(o);
  const LevelCamera base{camera->intrinsics()[0], camera->intrinsics()[1], camera->intrinsics()[2],
                         camera->intrinsics()[3], o.width, o.height};
  const auto cameras = make_level_cameras(base, usable_levels(o.width, o.height, 5, 40));
  InitializerOptions parallel_options = options;
  parallel_options.parallel_hypotheses = true;
  InitializerOptions sequential_options = parallel_options;
  sequential_options.parallel_hypotheses = false;
  CoarseInitializer parallel(cameras, parallel_options);
  CoarseInitializer sequential(cameras, sequential_options);

  bool first = true;
  int frames_after_snap = 0;
  while (auto f = simulator.next()) {
    cv::Mat image;
    const double scale = f->frame.image.depth() == CV_16U ? 255.0 / f->frame.max_value() : 1.0;
    f->frame.image.convertTo(image, CV_32F, scale);
    auto pyramid = std::make_shared<const ImagePyramid>(image, static_cast<int>(cameras.size()));
    if (first) {
      parallel.set_first(pyramid, 1.0);
      sequential.set_first(pyramid, 1.0);
      first = false;
      continue;
    }
    const InitializerState a = parallel.add_frame(pyramid, 1.0);
    const InitializerState b = sequential.add_frame(pyramid, 1.0);
    ASSERT_EQ(a, b);
    ASSERT_EQ(parallel.snapped(), sequential.snapped());
    frames_after_snap += parallel.snapped() ? 1 : 0;
    EXPECT_EQ((parallel.T_frame_first().log() - sequential.T_frame_first().log()).norm(), 0.0);
    EXPECT_EQ(parallel.affine_a(), sequential.affine_a());
    EXPECT_EQ(parallel.affine_b(), sequential.affine_b());
    ASSERT_EQ(parallel.points().size(), sequential.points().size());
    for (std::size_t i = 0; i < parallel.points().size(); ++i) {
      ASSERT_EQ(parallel.points()[i].inverse_depth, sequential.points()[i].inverse_depth) << "point " << i;
      ASSERT_EQ(parallel.points()[i].good, sequential.points()[i].good) << "point " << i;
    }
    if (a != InitializerState::Tracking) break;
  }
  // The hypotheses were aligned on some frames (the snap came, then frames_after_snap more),
  // and the initialiser finished.
  EXPECT_GT(frames_after_snap, 1);
  EXPECT_EQ(parallel.state(), InitializerState::Succeeded);
  // The frames since the snap, as the kept hypothesis has them: kept only for the joint
  // refinement, the last one is the handed-over pose.
  const auto poses = parallel.post_snap_poses();
  if (!options.joint_refinement) {
    EXPECT_TRUE(poses.empty());
    return;
  }
  ASSERT_EQ(static_cast<int>(poses.size()), frames_after_snap - 1);  // the snap frame is not kept
  EXPECT_EQ(poses.back().first, parallel.frames_tracked());
  EXPECT_EQ((poses.back().second.log() - parallel.T_frame_first().log()).norm(), 0.0);
  const auto sequential_poses = sequential.post_snap_poses();
  ASSERT_EQ(sequential_poses.size(), poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i)
    EXPECT_EQ((poses[i].second.log() - sequential_poses[i].second.log()).norm(), 0.0) << "frame " << poses[i].first;
}

TEST(CoarseInitializer, ParallelHypothesesGiveTheSameResultAsSequential) {
  InitializerOptions options;
  options.points = 800;
  expect_parallel_equals_sequential(options);
}

TEST(CoarseInitializer, DirectionSearchGivesTheSameResultOnTwoThreads) {
  // Fewer points and one cone of candidates (6 + the 4 starts), to stay short.
  InitializerOptions options;
  options.points = 300;
  options.patch_offset_invariant = true;
  options.joint_refinement = true;
  options.direction_rings = 1;
  options.select_by_mean_visible_energy = true;
  options.frames_after_snap = 5;
  expect_parallel_equals_sequential(options);
}

// The tunnel at 20 W at half size (as above), fed to several initialisers in lockstep until all
// have finished; returns the frame count each finished on (frames_tracked()).
std::vector<int> run_in_lockstep(std::vector<CoarseInitializer*> initializers) {
  SimulatorOptions o;
  o.scene = sim::SceneKind::Tunnel;
  o.powers_w = {20.0};
  o.frames = 30;
  o.width = 320;
  o.height = 240;
  o.supersampling = 1;
  Simulator simulator(o);
  const auto levels = static_cast<int>(usable_levels(o.width, o.height, 5, 40));
  std::vector<int> finished(initializers.size(), -1);
  bool first = true;
  while (auto f = simulator.next()) {
    cv::Mat image;
    const double scale = f->frame.image.depth() == CV_16U ? 255.0 / f->frame.max_value() : 1.0;
    f->frame.image.convertTo(image, CV_32F, scale);
    auto pyramid = std::make_shared<const ImagePyramid>(image, levels);
    bool running = false;
    for (std::size_t k = 0; k < initializers.size(); ++k) {
      if (first) {
        initializers[k]->set_first(pyramid, 1.0);
        running = true;
        continue;
      }
      if (finished[k] >= 0) continue;
      if (initializers[k]->add_frame(pyramid, 1.0) != InitializerState::Tracking)
        finished[k] = initializers[k]->frames_tracked();
      else
        running = true;
    }
    first = false;
    if (!running) break;
  }
  return finished;
}

std::vector<LevelCamera> half_size_tunnel_cameras() {
  SimulatorOptions o;
  o.scene = sim::SceneKind::Tunnel;
  o.width = 320;
  o.height = 240;
  const auto camera = make_sim_camera(o);
  const LevelCamera base{camera->intrinsics()[0], camera->intrinsics()[1], camera->intrinsics()[2],
                         camera->intrinsics()[3], o.width, o.height};
  return make_level_cameras(base, usable_levels(o.width, o.height, 5, 40));
}

InitializerOptions cheap_search_options() {
  InitializerOptions options;
  options.points = 300;
  options.patch_offset_invariant = true;
  options.joint_refinement = true;
  options.direction_rings = 1;
  options.select_by_mean_visible_energy = true;
  options.frames_after_snap = 5;
  options.plain_starts = true;
  options.plain_pre_snap = true;
  options.plain_hand_over_frames = 3;
  options.prune_after_frames = 2;
  options.candidates_kept = 2;
  return options;
}

void expect_same_result(const CoarseInitializer& x, const CoarseInitializer& y) {
  EXPECT_EQ((x.T_frame_first().log() - y.T_frame_first().log()).norm(), 0.0);
  EXPECT_EQ(x.affine_a(), y.affine_a());
  EXPECT_EQ(x.affine_b(), y.affine_b());
  ASSERT_EQ(x.points().size(), y.points().size());
  for (std::size_t i = 0; i < x.points().size(); ++i) {
    ASSERT_EQ(x.points()[i].inverse_depth, y.points()[i].inverse_depth) << "point " << i;
    ASSERT_EQ(x.points()[i].good, y.points()[i].good) << "point " << i;
  }
}

TEST(CoarseInitializer, CheapDirectionSearchGivesTheSameResultOnTwoThreads) {
  // The plain starts, the gate, the candidates' catch-up and their pruning; a margin no start
  // can beat keeps the gate from handing over, so the search runs to its joint refinement.
  InitializerOptions options = cheap_search_options();
  options.hypothesis_margin = 1.0;
  expect_parallel_equals_sequential(options);
}

TEST(CoarseInitializer, PlainGateHandsOverThePathWithoutTheSearch) {
  // A margin every start beats (energy below 11 times the pre-snap one's) makes the gate fire:
  // the initialiser then ends on the gate's frame with what it gives without the search (plain
  // residuals, four starts), to the bit, and hands no refined poses over.
  InitializerOptions search = cheap_search_options();
  search.hypothesis_margin = -10.0;
  InitializerOptions plain;
  plain.points = search.points;
  plain.hypothesis_margin = search.hypothesis_margin;
  plain.frames_after_snap = search.plain_hand_over_frames;
  const auto cameras = half_size_tunnel_cameras();
  CoarseInitializer with_search(cameras, search);
  CoarseInitializer without(cameras, plain);
  const auto finished = run_in_lockstep({&with_search, &without});
  EXPECT_EQ(with_search.state(), InitializerState::Succeeded);
  EXPECT_GT(finished[0], search.plain_hand_over_frames);
  EXPECT_EQ(finished[0], finished[1]);
  expect_same_result(with_search, without);
  EXPECT_TRUE(with_search.post_snap_poses().empty());
}

TEST(CoarseInitializer, SearchFallsBackToThePlainPathWhenNoHypothesisPassesTheChecks) {
  // No refined hypothesis can pass an inlier fraction above 1: the hand-over is the plain
  // path's choice (the pre-snap start, as no other beats a margin of 1), the same to the bit as
  // the initialiser without the search ending on the same frame.
  InitializerOptions search = cheap_search_options();
  search.hypothesis_margin = 1.0;
  search.hand_over_min_inlier_fraction = 1.01;
  InitializerOptions plain;
  plain.points = search.points;
  plain.hypothesis_margin = search.hypothesis_margin;
  plain.frames_after_snap = search.frames_after_snap;
  const auto cameras = half_size_tunnel_cameras();
  CoarseInitializer with_search(cameras, search);
  CoarseInitializer without(cameras, plain);
  const auto finished = run_in_lockstep({&with_search, &without});
  EXPECT_EQ(with_search.state(), InitializerState::Succeeded);
  EXPECT_EQ(finished[0], finished[1]);
  expect_same_result(with_search, without);
  // The plain path's own frame-by-frame poses, one per frame aligned after the snap frame.
  EXPECT_EQ(static_cast<int>(with_search.post_snap_poses().size()), search.frames_after_snap);
}

}  // namespace
}  // namespace nirslam::odometry
