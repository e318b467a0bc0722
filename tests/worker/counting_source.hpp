#pragma once

// A dataset-like source for the worker and source tests: `count` small frames whose pixel value
// is the frame index, with failures, reading time and seeking as a test asks for them.

#include <atomic>
#include <chrono>
#include <set>
#include <string>
#include <thread>

#include <opencv2/core.hpp>

#include "nirslam/common/error.hpp"
#include "nirslam/sources/source.hpp"

namespace nirslam::testing {

struct CountingOptions {
  int count = 10;
  double period_s = 0.05;                   // between timestamps
  std::set<int> corrupt;                    // these frames throw InputError naming "frames/000N.png"; the stream goes on after them
  int wrong_type_index = -1;                // this frame is CV_32FC1, not a grey image
  std::chrono::microseconds read_time{0};   // each next() takes this long
  bool seekable = false;
};

class CountingSource final : public Source {
public:
  explicit CountingSource(CountingOptions options) : options_(std::move(options)) {
    info_.kind = "test";
    info_.description = "counting source";
    info_.frame_count = static_cast<std::size_t>(options_.count);
    info_.seekable = options_.seekable;
  }
  const SourceInfo& info() const override { return info_; }
  std::optional<Frame> next() override {
    ++calls_;
    if (options_.read_time.count() > 0) std::this_thread::sleep_for(options_.read_time);
    if (index_ >= options_.count) return std::nullopt;
    const int index = index_++;
    if (options_.corrupt.count(index) != 0) throw InputError("frames/000" + std::to_string(index) + ".png", "corrupt PNG");
    Frame frame;
    frame.image = cv::Mat(8, 8, index == options_.wrong_type_index ? CV_32FC1 : CV_8UC1, cv::Scalar(index % 256));
    frame.index = index;
    frame.timestamp_s = index * options_.period_s;
    frame.name = "frame " + std::to_string(index);
    return frame;
  }
  void rewind() override { index_ = 0; }
  void seek(std::size_t position) override {
    if (!info_.seekable) return Source::seek(position);
    require_frame_position(position, static_cast<std::size_t>(options_.count));
    index_ = static_cast<int>(position);
  }
  // next() calls so far (read from any thread).
  int calls() const { return calls_.load(); }

private:
  CountingOptions options_;
  SourceInfo info_;
  int index_ = 0;
  std::atomic<int> calls_{0};
};

}  // namespace nirslam::testing
