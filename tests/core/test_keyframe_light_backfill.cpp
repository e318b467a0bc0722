// The lamp's distance for the calibration's earlier keyframes once a track has its point: the
// distance is the point's from the lamp at each keyframe's own pose (and power), a track stops
// waiting once answered or ended, and keyframes not placed, lost or of another odometry segment
// give nothing.
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "nirslam/photometric/photometric_tracker.hpp"
#include "nirslam/pipeline/keyframe_light_backfill.hpp"

namespace nirslam {
namespace {

// The rig drives along z and turns a little, 5 cm a frame.
SE3 backfill_rig_pose(int frame) {
  return SE3(Eigen::AngleAxisd(0.01 * frame, Eigen::Vector3d::UnitY()).toRotationMatrix(), Eigen::Vector3d(0.0, 0.0, 0.05 * frame));
}

std::vector<TrackObservation> live_tracks(std::initializer_list<std::int64_t> ids) {
  std::vector<TrackObservation> out;
  for (const std::int64_t id : ids) {
    TrackObservation t;
    t.id = id;
    t.samples.setZero();
    t.reference.setZero();
    out.push_back(t);
  }
  return out;
}

TEST(KeyframeLightBackfill, EachKeyframeTakesTheDistanceAtItsOwnPoseAndPower) {
  const Eigen::Vector3d light_offset(0.05, -0.02, 0.0);
  const std::vector<Eigen::Vector3d> points = {{0.4, 1.0, 6.0}, {-0.8, 0.9, 4.5}, {0.1, -0.5, 8.0}};
  const auto point_of = [&](std::int64_t id) -> std::optional<Eigen::Vector3d> {
    if (id == 1 || id == 2) return points[static_cast<std::size_t>(id)];
    return std::nullopt;  // track 0 never gets a point
  };
  KeyframeLightBackfill backfill;
  const std::vector<int> keyframe_frames = {0, 4, 8};
  for (const int frame : keyframe_frames) {
    backfill.add_keyframe(frame, 20.0 + frame, {0, 1, 2});
    backfill.place_keyframe(frame, backfill_rig_pose(frame), 3);
  }
  EXPECT_EQ(backfill.pending_tracks(), 9u);
  const std::vector<TrackObservation> all = live_tracks({0, 1, 2});
  const std::vector<KeyframeIllumination> found = backfill.resolve(3, point_of, all, light_offset);
  ASSERT_EQ(found.size(), 3u);
  for (std::size_t k = 0; k < found.size(); ++k) {
    const int frame = keyframe_frames[k];
    EXPECT_EQ(found[k].frame_index, frame);
    ASSERT_EQ(found[k].values.size(), 2u);
    for (const TrackIllumination& value : found[k].values) {
      const Eigen::Vector3d p_cam = backfill_rig_pose(frame).inverse() * points[static_cast<std::size_t>(value.track_id)];
      const double distance = (p_cam - light_offset).norm();
      EXPECT_NEAR(value.log_illumination, std::log(20.0 + frame) - 2.0 * std::log(distance), 1e-12)
          << "frame " << frame << ", track " << value.track_id;
    }
  }
  EXPECT_EQ(backfill.pending_tracks(), 3u) << "answered tracks stop waiting";
  EXPECT_TRUE(backfill.resolve(3, point_of, all, light_offset).empty()) << "answered once";
  // Track 0 ends without a point: it stops waiting, and so do its keyframes.
  EXPECT_TRUE(backfill.resolve(3, point_of, live_tracks({1, 2}), light_offset).empty());
  EXPECT_EQ(backfill.pending_keyframes(), 0u);
}

TEST(KeyframeLightBackfill, KeyframesNotPlacedLostOrOfAnotherSegmentGiveNothing) {
  const auto everywhere = [](std::int64_t) -> std::optional<Eigen::Vector3d> { return Eigen::Vector3d(0.0, 0.0, 10.0); };
  const std::vector<TrackObservation> tracks = live_tracks({5});
  KeyframeLightBackfill backfill;
  backfill.add_keyframe(10, 1.0, {5});
  EXPECT_TRUE(backfill.resolve(0, everywhere, tracks, Eigen::Vector3d::Zero()).empty()) << "its pose is not known yet";
  EXPECT_EQ(backfill.pending_keyframes(), 1u);
  backfill.place_keyframe(10, std::nullopt, 0);
  EXPECT_EQ(backfill.pending_keyframes(), 0u) << "a frame the odometry did not track is forgotten";

  backfill.add_keyframe(11, 1.0, {5});
  backfill.place_keyframe(11, backfill_rig_pose(11), 0);
  EXPECT_TRUE(backfill.resolve(1, everywhere, tracks, Eigen::Vector3d::Zero()).empty()) << "points of another world frame";
  EXPECT_EQ(backfill.pending_keyframes(), 0u);

  // A point behind the keyframe's camera answers the track with nothing.
  backfill.add_keyframe(12, 1.0, {5});
  backfill.place_keyframe(12, backfill_rig_pose(12), 0);
  const auto behind = [](std::int64_t) -> std::optional<Eigen::Vector3d> { return Eigen::Vector3d(0.0, 0.0, -3.0); };
  EXPECT_TRUE(backfill.resolve(0, behind, tracks, Eigen::Vector3d::Zero()).empty());
  EXPECT_EQ(backfill.pending_keyframes(), 0u);

  // A keyframe whose every track already had a distance does not wait at all.
  backfill.add_keyframe(13, 1.0, {});
  EXPECT_EQ(backfill.pending_keyframes(), 0u);
}

// With the lamp's cosine: the held normal's cosine at the keyframe's pose; a track with its point
// but no normal yet waits for it, and a grazing one gives nothing.
TEST(KeyframeLightBackfill, WithNormalsTheCosineAtTheKeyframesPoseToo) {
  const Eigen::Vector3d light_offset(0.05, 0.0, 0.0);
  const Eigen::Vector3d floor_point(0.3, 1.0, 5.0), floor_normal(0.0, -1.0, 0.0);  // camera y points down
  bool normal_known = false;
  const auto point_of = [&](std::int64_t id) -> std::optional<Eigen::Vector3d> {
    if (id == 1) return floor_point;
    if (id == 2) return Eigen::Vector3d(0.0, 0.0, 40.0);  // far ahead on the floor plane's normal side: grazing
    return std::nullopt;
  };
  const auto normal_of = [&](std::int64_t id) -> std::optional<Eigen::Vector3d> {
    if (id == 1 && normal_known) return floor_normal;
    if (id == 2) return Eigen::Vector3d(1.0, 0.0, 0.0);  // a wall the lamp's rays skim
    return std::nullopt;
  };
  KeyframeLightBackfill backfill;
  backfill.add_keyframe(2, 50.0, {1, 2});
  backfill.place_keyframe(2, backfill_rig_pose(2), 0);
  const std::vector<TrackObservation> tracks = live_tracks({1, 2});
  EXPECT_TRUE(backfill.resolve(0, point_of, tracks, light_offset, normal_of).empty());
  EXPECT_EQ(backfill.pending_tracks(), 1u) << "track 1 waits for its normal, track 2 grazes and is answered with nothing";
  normal_known = true;
  const std::vector<KeyframeIllumination> found = backfill.resolve(0, point_of, tracks, light_offset, normal_of);
  ASSERT_EQ(found.size(), 1u);
  ASSERT_EQ(found[0].values.size(), 1u);
  const Eigen::Vector3d lamp = backfill_rig_pose(2) * light_offset;
  const double distance = (lamp - floor_point).norm();
  const double cosine = floor_normal.dot(lamp - floor_point) / distance;
  ASSERT_GT(cosine, 0.05);
  EXPECT_NEAR(found[0].values[0].log_illumination, std::log(50.0 * cosine) - 2.0 * std::log(distance), 1e-12);
  EXPECT_EQ(backfill.pending_keyframes(), 0u);
}

TEST(KeyframeLightBackfill, AtMostTheConfiguredKeyframesWaitTheOldestGoingFirst) {
  KeyframeLightBackfillOptions options;
  options.max_pending_keyframes = 4;
  KeyframeLightBackfill backfill(options);
  for (int frame = 0; frame < 10; ++frame) {
    backfill.add_keyframe(frame, 1.0, {1});
    backfill.place_keyframe(frame, backfill_rig_pose(frame), 0);
  }
  EXPECT_EQ(backfill.pending_keyframes(), 4u);
  const auto point = [](std::int64_t) -> std::optional<Eigen::Vector3d> { return Eigen::Vector3d(0.0, 0.0, 10.0); };
  const std::vector<KeyframeIllumination> found = backfill.resolve(0, point, live_tracks({1}), Eigen::Vector3d::Zero());
  ASSERT_EQ(found.size(), 4u);
  EXPECT_EQ(found.front().frame_index, 6);
  EXPECT_EQ(found.back().frame_index, 9);
}

}  // namespace
}  // namespace nirslam
