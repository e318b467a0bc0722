#include "nirslam/pipeline/held_per_track.hpp"

#include <gtest/gtest.h>

namespace nirslam {
namespace {

TEST(HeldPerTrack, KeepsATrackAskedForAndForgetsOneLeftAlone) {
  HeldPerTrack<int> held(/*forget_after_frames=*/2);
  held.begin_frame(0);
  held.hold(1, 10);
  held.hold(2, 20);
  for (int frame = 0; frame < 5; ++frame) {
    held.begin_frame(0);
    const int* value = held.touch(1);
    ASSERT_NE(value, nullptr) << "frame " << frame;
    EXPECT_EQ(*value, 10);
  }
  // Track 2 was held but not asked for: gone after two frames; find() alone does not keep a track.
  EXPECT_FALSE(held.contains(2));
  EXPECT_EQ(held.size(), 1u);
  held.begin_frame(0);
  held.begin_frame(0);
  EXPECT_NE(held.find(1), nullptr);
  held.begin_frame(0);
  EXPECT_EQ(held.find(1), nullptr);
}

TEST(HeldPerTrack, ANewSegmentOrClearStartsOver) {
  HeldPerTrack<double> held(5);
  held.begin_frame(3);
  held.hold(7, 1.5);
  held.begin_frame(3);
  EXPECT_TRUE(held.contains(7));
  held.begin_frame(4);
  EXPECT_FALSE(held.contains(7));
  held.hold(8, 2.5);
  held.clear();
  EXPECT_EQ(held.size(), 0u);
  // After clear() the same segment number counts as new, and holding again replaces the value.
  held.begin_frame(4);
  held.hold(8, 3.0);
  held.hold(8, 4.0);
  const double* value = held.find(8);
  ASSERT_NE(value, nullptr);
  EXPECT_EQ(*value, 4.0);
}

}  // namespace
}  // namespace nirslam
