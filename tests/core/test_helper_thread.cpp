// The odometry's persistent second thread: both parts of a split run, on two threads, every
// time; an exception of either part reaches the caller and leaves the thread usable.

#include <atomic>
#include <stdexcept>
#include <thread>

#include <gtest/gtest.h>

#include "nirslam/common/helper_thread.hpp"

namespace nirslam {
namespace {

TEST(HelperThread, RunsBothPartsOnTwoThreadsEveryTime) {
  HelperThread helper;
  std::thread::id helper_id;
  for (int round = 0; round < 200; ++round) {
    int caller_part = 0;
    int helper_part = 0;
    std::thread::id caller_seen;
    std::thread::id helper_seen;
    helper.run([&] { caller_part = round; caller_seen = std::this_thread::get_id(); },
               [&] { helper_part = round + 1; helper_seen = std::this_thread::get_id(); });
    ASSERT_EQ(caller_part, round);
    ASSERT_EQ(helper_part, round + 1);
    ASSERT_EQ(caller_seen, std::this_thread::get_id());
    ASSERT_NE(helper_seen, std::this_thread::get_id());
    if (round == 0) helper_id = helper_seen;
    ASSERT_EQ(helper_seen, helper_id) << "the same helper thread serves every call";
  }
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
