#include "nirslam/sources/read_ahead.hpp"

#include <condition_variable>
#include <deque>
#include <exception>
#include <mutex>
#include <stdexcept>
#include <thread>

namespace nirslam {
namespace {

class ReadAhead final : public Source {
public:
  ReadAhead(std::unique_ptr<Source> inner, std::size_t depth)
      : inner_(std::move(inner)),
        depth_(depth),
        info_(inner_->info()),
        camera_(inner_->camera()),
        truth_(inner_->photometric_truth()) {
    start_reader();
  }
  ~ReadAhead() override { stop_reader(); }

  const SourceInfo& info() const override { return info_; }
  std::shared_ptr<const CameraModel> camera() const override { return camera_; }
  std::optional<PhotometricTruth> photometric_truth() const override { return truth_; }
  std::string end_reason() const override {
    const std::lock_guard lock(mutex_);
    return end_reason_;
  }

  std::optional<Frame> next() override {
    std::unique_lock lock(mutex_);
    filled_.wait(lock, [this] { return !queue_.empty() || ended_; });
    if (queue_.empty()) return std::nullopt;  // the stream ended and every frame was taken
    Item item = std::move(queue_.front());
    queue_.pop_front();
    ++position_;
    lock.unlock();
    emptied_.notify_one();
    if (item.error) std::rethrow_exception(item.error);
    return std::move(item.frame);
  }

  void rewind() override {
    restart_reader([this] { inner_->rewind(); });
    position_ = 0;
  }

  void seek(std::size_t position) override {
    if (!info_.seekable) return Source::seek(position);
    if (info_.frame_count) require_frame_position(position, *info_.frame_count);
    try {
      restart_reader([this, position] { inner_->seek(position); });
    } catch (...) {
      // The frames read ahead are gone: the source goes back to where the consumer was.
      restart_reader([this] { inner_->seek(position_); });
      throw;
    }
    position_ = position;
  }

private:
  struct Item {
    std::optional<Frame> frame;
    std::exception_ptr error;
  };

  // Stops the reader, drops what it read ahead, moves the source and reads on from there.
  template <typename MoveSource>
  void restart_reader(MoveSource&& move_source) {
    stop_reader();
    queue_.clear();
    ended_ = false;
    end_reason_.clear();
    stopping_ = false;
    std::exception_ptr error;
    try {
      move_source();
    } catch (...) {
      error = std::current_exception();
    }
    start_reader();
    if (error) std::rethrow_exception(error);
  }

  void start_reader() {
    reader_ = std::thread([this] { read_loop(); });
  }
  void stop_reader() {
    {
      const std::lock_guard lock(mutex_);
      stopping_ = true;
    }
    emptied_.notify_all();
    if (reader_.joinable()) reader_.join();
  }

  void read_loop() {
    for (;;) {
      {
        std::unique_lock lock(mutex_);
        emptied_.wait(lock, [this] { return stopping_ || queue_.size() < depth_; });
        if (stopping_) return;
      }
      // Read outside the lock: the consumer takes earlier frames meanwhile.
      Item item;
      try {
        item.frame = inner_->next();
      } catch (...) {
        // Kept in its place; the reader goes on as the consumer's own next() calls would.
        item.error = std::current_exception();
      }
      const bool end = !item.frame && !item.error;
      std::string end_reason = end ? inner_->end_reason() : std::string();
      {
        const std::lock_guard lock(mutex_);
        if (end) {
          ended_ = true;
          end_reason_ = std::move(end_reason);
        } else {
          queue_.push_back(std::move(item));
        }
      }
      filled_.notify_one();
      if (end) return;
    }
  }

  std::unique_ptr<Source> inner_;  // used by the reader thread only, while it runs
  const std::size_t depth_;
  const SourceInfo info_;
  const std::shared_ptr<const CameraModel> camera_;
  const std::optional<PhotometricTruth> truth_;

  mutable std::mutex mutex_;
  std::condition_variable filled_;   // a frame, an error or the end was queued
  std::condition_variable emptied_;  // room in the queue, or stopping
  std::deque<Item> queue_;
  bool ended_ = false;
  std::string end_reason_;  // the source's, when it ended
  bool stopping_ = false;
  std::size_t position_ = 0;  // items the consumer took since the last rewind or seek (consumer only)
  std::thread reader_;
};

}  // namespace

std::unique_ptr<Source> read_ahead(std::unique_ptr<Source> source, std::size_t depth) {
  if (!source) throw std::invalid_argument("read_ahead: no source");
  if (depth == 0 || source->info().live || source->illuminator() != nullptr || source->camera_controls() != nullptr)
    return source;
  return std::make_unique<ReadAhead>(std::move(source), depth);
}

}  // namespace nirslam
