// The persistent second thread of the two-way splits: both parts of a split run exactly once
// every time (on whichever thread is free); an exception of either part reaches the caller and
// leaves the thread usable.

#include <atomic>
#include <cstdio>
#include <stdexcept>
#include <thread>

#include <gtest/gtest.h>

#include "nirslam/common/helper_thread.hpp"

namespace nirslam {
namespace {

TEST(HelperThread, RunsEachPartOnceEveryTime) {
  HelperThread helper;
  std::atomic<int> on_helper{0};
  for (int round = 0; round < 500; ++round) {
    std::atomic<int> runs_0{0};
    std::atomic<int> runs_1{0};
    int value_0 = -1;
    int value_1 = -1;
    const std::thread::id caller = std::this_thread::get_id();
    helper.run(
        [&] {
          ++runs_0;
          value_0 = round;
          if (std::this_thread::get_id() != caller) ++on_helper;
        },
        [&] {
          ++runs_1;
          value_1 = 2 * round;
          if (std::this_thread::get_id() != caller) ++on_helper;
        });
    ASSERT_EQ(runs_0.load(), 1);
    ASSERT_EQ(runs_1.load(), 1);
    ASSERT_EQ(value_0, round);  // both parts' writes are visible when run() returns
    ASSERT_EQ(value_1, 2 * round);
  }
  // Which thread ran a part is up to the scheduler (a caller that finds a part free takes it),
  // so only the count is printed, not checked.
  std::printf("parts run on the helper thread: %d of 1000\n", on_helper.load());
}

TEST(HelperThread, ExceptionsOfEitherPartReachTheCaller) {
  HelperThread helper;
  std::atomic<bool> other_ran{false};
  EXPECT_THROW(helper.run([&] { other_ran = true; }, [] { throw std::runtime_error("helper"); }), std::runtime_error);
  EXPECT_TRUE(other_ran);
  other_ran = false;
  EXPECT_THROW(helper.run([] { throw std::invalid_argument("caller"); }, [&] { other_ran = true; }),
               std::invalid_argument);
  EXPECT_TRUE(other_ran) << "the helper's part finishes before the caller's exception leaves";
  int sum = 0;
  helper.run([&] { sum += 1; }, [&] { sum += 0; });
  EXPECT_EQ(sum, 1);
}

TEST(HelperThread, SplitInTwoCoversTheRangeOnceAndKeepsSmallCountsOnTheCaller) {
  HelperThread helper;
  std::vector<int> hits(1000, 0);
  split_in_two(helper, hits.size(), 400, 256, [&](std::size_t begin, std::size_t end, int) {
    for (std::size_t i = begin; i < end; ++i) ++hits[i];
  });
  for (int h : hits) ASSERT_EQ(h, 1);
  int parts = 0;
  split_in_two(helper, 10, 5, 256, [&](std::size_t begin, std::size_t end, int part) {
    EXPECT_EQ(begin, 0u);
    EXPECT_EQ(end, 10u);
    EXPECT_EQ(part, 0);
    ++parts;
  });
  EXPECT_EQ(parts, 1);
}

}  // namespace
}  // namespace nirslam
