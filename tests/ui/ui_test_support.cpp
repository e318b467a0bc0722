#include "ui/ui_test_support.hpp"

#include <cstdlib>
#include <filesystem>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "nirslam/image/image_codec.hpp"
#include "nirslam/quality/image_quality.hpp"

namespace nirslam::ui::testing {

void save_if_requested(const cv::Mat& rgba, const std::string& name) {
  const char* dir = std::getenv("NIRSLAM_UI_TEST_SHOTS");
  if (dir == nullptr || *dir == '\0') return;
  std::filesystem::create_directories(dir);
  cv::Mat bgr;
  cv::cvtColor(rgba, bgr, cv::COLOR_RGBA2BGR);
  nirslam::write_image((std::filesystem::path(dir) / (name + ".png")), bgr);
}

Snapshot snapshot_with_frame(Frame frame) {
  Snapshot snapshot;
  snapshot.sequence = 1;
  snapshot.state = WorkerState::Paused;
  snapshot.source.kind = "test";
  snapshot.source.description = "hand-made test frame";
  snapshot.source.frame_count = 10;
  snapshot.quality = measure_quality(frame, &snapshot.histogram);
  snapshot.quality_history.push_back({frame.index, frame.timestamp_s, snapshot.quality});
  snapshot.frames_processed = frame.index + 1;
  snapshot.processing_fps = 30.0;
  snapshot.frame = std::move(frame);
  snapshot.message = "paused";
  return snapshot;
}

}  // namespace nirslam::ui::testing
