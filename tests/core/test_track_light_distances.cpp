// The lamp distance of a tracked patch from its own track (issue 8): the track's rays, placed by
// the odometry's poses, meet at the surface point; no distance until they span the parallax, none
// for a track whose rays disagree, and nothing carried over a lost track or a new segment.
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "nirslam/photometric/photometric_tracker.hpp"
#include "nirslam/pipeline/track_light_distances.hpp"
#include "core/pinhole_camera_640.hpp"

namespace nirslam {
namespace {

// A camera moving along x (looking along z) by `step` metres a frame.
SE3 pose_at(int frame, double step) { return SE3(Eigen::Matrix3d::Identity(), Eigen::Vector3d(step * frame, 0.0, 0.0)); }

TrackObservation observe(const CameraModel& camera, std::int64_t id, const Eigen::Vector3d& p_world, const SE3& T_world_cam,
                         const Eigen::Vector2d& pixel_error = Eigen::Vector2d::Zero()) {
  TrackObservation track;
  track.samples.setZero();  // not read here; set so that copies of the track copy values
  track.reference.setZero();
  track.id = id;
  track.position = *camera.project(T_world_cam.inverse() * p_world) + pixel_error;
  return track;
}

TEST(TrackLightDistances, RaysThatSpanTheParallaxGiveTheLampDistance) {
  const PinholeCamera camera = pinhole_camera_640();
  TrackLightDistances distances(camera);  // 3 degrees, 3 rays, 1.5 px
  const Eigen::Vector3d p_world(0.3, -0.2, 2.0);
  const Eigen::Vector3d light_offset(0.05, 0.0, 0.0);
  // 1 cm a frame at 2 m: 0.29 degrees a frame, so the point is known from the 12th ray on.
  int first_known = -1;
  for (int frame = 0; frame < 20; ++frame) {
    const std::vector<TrackObservation> tracks{observe(camera, 7, p_world, pose_at(frame, 0.01))};
    distances.add_frame(tracks, pose_at(frame, 0.01), 0);
    if (first_known < 0 && distances.point_world(7)) first_known = frame;
  }
  EXPECT_EQ(first_known, 11);
  ASSERT_TRUE(distances.point_world(7));
  EXPECT_LT((*distances.point_world(7) - p_world).norm(), 1e-9);
  // The distance from the lamp (beside the lens) at any pose, e.g. one the caller predicted.
  const SE3 predicted = pose_at(25, 0.01);
  const auto d = distances.light_distance(7, predicted, light_offset);
  ASSERT_TRUE(d);
  EXPECT_NEAR(*d, (predicted.inverse() * p_world - light_offset).norm(), 1e-9);
  // Behind that camera: none.
  const SE3 turned(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()).toRotationMatrix(), Eigen::Vector3d::Zero());
  EXPECT_FALSE(distances.light_distance(7, turned, light_offset));
  EXPECT_FALSE(distances.light_distance(8, predicted, light_offset));  // an unknown track
}

TEST(TrackLightDistances, NoisyRaysStillLocateThePointToAFewPerCent) {
  const PinholeCamera camera = pinhole_camera_640();
  TrackLightDistances distances(camera);
  const Eigen::Vector3d p_world(-0.4, 0.1, 3.0);
  // Half a pixel of alternating error on every ray, 30 frames of 2 cm: 11 degrees of parallax.
  for (int frame = 0; frame < 30; ++frame) {
    const Eigen::Vector2d error(frame % 2 == 0 ? 0.5 : -0.5, frame % 3 == 0 ? 0.5 : -0.25);
    const std::vector<TrackObservation> tracks{observe(camera, 1, p_world, pose_at(frame, 0.02), error)};
    distances.add_frame(tracks, pose_at(frame, 0.02), 0);
  }
  const auto d = distances.light_distance(1, SE3::identity(), Eigen::Vector3d::Zero());
  ASSERT_TRUE(d);
  EXPECT_NEAR(*d, p_world.norm(), 0.02 * p_world.norm());
}

TEST(TrackLightDistances, ATrackThatSlidGivesNoDistance) {
  const PinholeCamera camera = pinhole_camera_640();
  TrackLightDistances distances(camera);
  const Eigen::Vector3d p_world(0.2, 0.0, 2.0);
  // Halfway the patch jumps to another surface 1 m further back (an occlusion edge): the rays
  // no longer meet.
  for (int frame = 0; frame < 40; ++frame) {
    const Eigen::Vector3d seen = frame < 20 ? p_world : Eigen::Vector3d(p_world + Eigen::Vector3d(0.0, 0.0, 1.0));
    const std::vector<TrackObservation> tracks{observe(camera, 3, seen, pose_at(frame, 0.02))};
    distances.add_frame(tracks, pose_at(frame, 0.02), 0);
    if (frame == 19) {
      EXPECT_TRUE(distances.point_world(3));
    }
  }
  EXPECT_FALSE(distances.point_world(3));
  EXPECT_EQ(distances.triangulated(), 0u);
}

TEST(TrackLightDistances, LostTracksAndNewSegmentsStartOver) {
  const PinholeCamera camera = pinhole_camera_640();
  TrackLightDistances distances(camera);
  const Eigen::Vector3d a(0.2, 0.0, 2.0), b(-0.3, 0.1, 2.5);
  for (int frame = 0; frame < 20; ++frame) {
    const std::vector<TrackObservation> tracks{observe(camera, 1, a, pose_at(frame, 0.02)), observe(camera, 2, b, pose_at(frame, 0.02))};
    distances.add_frame(tracks, pose_at(frame, 0.02), 0);
  }
  EXPECT_EQ(distances.triangulated(), 2u);
  // Track 2 is lost: forgotten.
  distances.add_frame(std::vector<TrackObservation>{observe(camera, 1, a, pose_at(20, 0.02))}, pose_at(20, 0.02), 0);
  EXPECT_EQ(distances.tracks(), 1u);
  EXPECT_TRUE(distances.point_world(1));
  EXPECT_FALSE(distances.point_world(2));
  // A new segment (the odometry reinitialised: new world frame and scale): track 1's rays of the
  // old one do not count.
  distances.add_frame(std::vector<TrackObservation>{observe(camera, 1, a, pose_at(21, 0.02))}, pose_at(21, 0.02), 1);
  EXPECT_FALSE(distances.point_world(1));
  distances.clear();
  EXPECT_EQ(distances.tracks(), 0u);
}

}  // namespace
}  // namespace nirslam
