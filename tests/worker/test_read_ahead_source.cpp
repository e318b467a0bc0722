// The read-ahead source (also run under ThreadSanitizer): the consumer sees exactly the frames,
// order and errors of the source it wraps, however fast either side is.

#include <atomic>
#include <chrono>
#include <memory>
#include <set>
#include <stdexcept>
#include <thread>

#include <gtest/gtest.h>

#include "nirslam/common/error.hpp"
#include "nirslam/sources/read_ahead.hpp"
#include "counting_source.hpp"

namespace nirslam {
namespace {

using testing::CountingOptions;
using testing::CountingSource;

// A seekable counting source whose frames in `corrupt` throw (and the stream goes on after them,
// as a folder reader's does).
std::unique_ptr<CountingSource> counting_source(int count, std::set<int> corrupt = {}, std::chrono::microseconds read_time = {}) {
  CountingOptions options;
  options.count = count;
  options.corrupt = std::move(corrupt);
  options.read_time = read_time;
  options.seekable = true;
  return std::make_unique<CountingSource>(options);
}

TEST(ReadAheadSource, DeliversEveryFrameInOrderThenTheEnd) {
  auto source = read_ahead(counting_source(40), 3);
  EXPECT_EQ(source->info().kind, "test");
  ASSERT_EQ(source->info().frame_count, std::optional<std::size_t>(40));
  for (int i = 0; i < 40; ++i) {
    auto frame = source->next();
    ASSERT_TRUE(frame) << "frame " << i;
    EXPECT_EQ(frame->index, i);
    EXPECT_EQ(frame->image.at<std::uint8_t>(2, 2), i);
    if (i % 7 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));  // a slow consumer now and then
  }
  EXPECT_FALSE(source->next());
  EXPECT_FALSE(source->next()) << "the end stays the end";
}

TEST(ReadAheadSource, AnErrorComesAtItsPlaceAfterTheFramesReadBeforeIt) {
  auto source = read_ahead(counting_source(10, {4}), 4);
  for (int i = 0; i < 4; ++i) {
    auto frame = source->next();
    ASSERT_TRUE(frame);
    EXPECT_EQ(frame->index, i);
  }
  try {
    source->next();
    FAIL() << "frame 4 must throw";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("frames/0004.png"), std::string::npos) << e.what();
  }
  auto after = source->next();  // as the wrapped source would go on
  ASSERT_TRUE(after);
  EXPECT_EQ(after->index, 5);
}

TEST(ReadAheadSource, ReadsNoFurtherAheadThanItsDepth) {
  auto wrapped = counting_source(100);
  const CountingSource& inner = *wrapped;
  auto source = read_ahead(std::move(wrapped), 3);
  ASSERT_TRUE(source->next());
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (inner.calls() < 4 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(inner.calls(), 4) << "the frame taken plus three ahead";
}

TEST(ReadAheadSource, RewindStartsOverWhileTheReaderIsBusy) {
  auto source = read_ahead(counting_source(30, {}, std::chrono::microseconds(200)), 4);
  for (int i = 0; i < 7; ++i) ASSERT_TRUE(source->next());
  source->rewind();
  for (int i = 0; i < 30; ++i) {
    auto frame = source->next();
    ASSERT_TRUE(frame);
    EXPECT_EQ(frame->index, i);
  }
  EXPECT_FALSE(source->next());
}

TEST(ReadAheadSource, SeekDropsWhatWasReadAheadAndGoesOnFromThere) {
  auto source = read_ahead(counting_source(50), 4);
  ASSERT_TRUE(source->info().seekable);
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(source->next());
  source->seek(30);
  for (int i = 30; i < 33; ++i) {
    auto frame = source->next();
    ASSERT_TRUE(frame);
    EXPECT_EQ(frame->index, i);
  }
  // Past the end: refused, and the stream goes on where it was.
  EXPECT_THROW(source->seek(50), std::out_of_range);
  auto frame = source->next();
  ASSERT_TRUE(frame);
  EXPECT_EQ(frame->index, 33);
  source->seek(2);
  frame = source->next();
  ASSERT_TRUE(frame);
  EXPECT_EQ(frame->index, 2);
}

TEST(ReadAheadSource, DestroyedWithAFullQueueDoesNotHang) {
  auto source = read_ahead(counting_source(1000), 2);
  ASSERT_TRUE(source->next());
  std::this_thread::sleep_for(std::chrono::milliseconds(5));
  source.reset();  // the reader waits for room; stopping must wake it
  SUCCEED();
}

TEST(ReadAheadSource, LiveSourcesAndZeroDepthAreLeftAsTheyAre) {
  class LiveSource final : public Source {
  public:
    LiveSource() { info_.live = true; }
    const SourceInfo& info() const override { return info_; }
    std::optional<Frame> next() override { return std::nullopt; }
    void rewind() override {}

  private:
    SourceInfo info_;
  };
  auto live = std::make_unique<LiveSource>();
  const Source* live_address = live.get();
  EXPECT_EQ(read_ahead(std::move(live)).get(), live_address);
  auto dataset = counting_source(3);
  const Source* dataset_address = dataset.get();
  EXPECT_EQ(read_ahead(std::move(dataset), 0).get(), dataset_address);
  EXPECT_THROW(read_ahead(nullptr), std::invalid_argument);
}

}  // namespace
}  // namespace nirslam
