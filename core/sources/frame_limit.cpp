#include "nirslam/sources/frame_limit.hpp"

#include <algorithm>
#include <stdexcept>

namespace nirslam {
namespace {

class FrameLimit final : public Source {
public:
  FrameLimit(std::unique_ptr<Source> inner, std::int64_t max_frames)
      : inner_(std::move(inner)), max_frames_(max_frames), info_(inner_->info()) {
    const auto limit = static_cast<std::size_t>(max_frames);
    info_.frame_count = info_.frame_count ? std::min(*info_.frame_count, limit) : limit;
  }
  const SourceInfo& info() const override { return info_; }
  std::optional<Frame> next() override {
    if (delivered_ >= max_frames_) return std::nullopt;
    auto frame = inner_->next();
    if (frame) ++delivered_;
    return frame;
  }
  void rewind() override {
    inner_->rewind();
    delivered_ = 0;
  }
  void seek(std::size_t position) override {
    require_frame_position(position, *info_.frame_count);
    inner_->seek(position);
    delivered_ = static_cast<std::int64_t>(position);
  }
  std::string end_reason() const override { return delivered_ >= max_frames_ ? std::string() : inner_->end_reason(); }
  std::int64_t frames_dropped() const override { return inner_->frames_dropped(); }
  std::shared_ptr<const CameraModel> camera() const override { return inner_->camera(); }
  std::shared_ptr<IlluminatorController> illuminator() const override { return inner_->illuminator(); }
  std::shared_ptr<CameraControls> camera_controls() const override { return inner_->camera_controls(); }
  std::optional<PhotometricTruth> photometric_truth() const override { return inner_->photometric_truth(); }

private:
  std::unique_ptr<Source> inner_;
  std::int64_t max_frames_;
  std::int64_t delivered_ = 0;
  SourceInfo info_;
};

}  // namespace

std::unique_ptr<Source> limit_frames(std::unique_ptr<Source> source, std::int64_t max_frames) {
  if (!source) throw std::invalid_argument("limit_frames: no source");
  if (max_frames <= 0) throw std::invalid_argument("limit_frames: max_frames must be positive");
  return std::make_unique<FrameLimit>(std::move(source), max_frames);
}

}  // namespace nirslam
