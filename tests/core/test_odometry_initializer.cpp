// The initialiser's hypotheses after its snap run on two threads (InitializerOptions::
// parallel_hypotheses): each is aligned on its own copy of the initialiser, so the result must be
// the same, to the last bit, as aligning them one after the other.

#include <memory>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "nirslam/odometry/coarse_initializer.hpp"
#include "nirslam/odometry/image_pyramid.hpp"
#include "nirslam/sim/simulator.hpp"
#include "simulator_fixtures.hpp"

namespace nirslam::odometry {
namespace {

void expect_parallel_equals_sequential(const InitializerOptions& options) {
  // The hand-held tunnel at 20 W (a bench sequence), at half size to keep the test short; the
  // parallax threshold is for a 640-wide image, so the snap comes as at full size.
  const SimulatorOptions o = test_sequences::lamp_sequence(sim::SceneKind::Tunnel, 20.0, 30);
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
}

TEST(CoarseInitializer, ParallelHypothesesGiveTheSameResultAsSequential) {
  InitializerOptions options;
  options.points = 800;
  expect_parallel_equals_sequential(options);
}

}  // namespace
}  // namespace nirslam::odometry
