#include "nirslam/session/metrics_csv_writer.hpp"

#include <cerrno>
#include <cstring>
#include <stdexcept>

#include <spdlog/fmt/fmt.h>

namespace nirslam {
namespace {

std::string csv_number_or_blank(const std::optional<double>& value) {
  return value ? fmt::format("{:.6f}", *value) : std::string();
}

}  // namespace

MetricsCsvWriter::MetricsCsvWriter(std::filesystem::path path) : path_(std::move(path)) {
  out_.open(path_, std::ios::out | std::ios::trunc);
  check("cannot create");
  out_ << kHeader << '\n' << std::flush;
  check("cannot write");
}

void MetricsCsvWriter::write(const Snapshot& snapshot) {
  if (!snapshot.frame) return;
  const Frame& frame = *snapshot.frame;
  const ImageQuality& q = snapshot.quality;
  const ImageStructure& st = snapshot.structure;
  const PipelineFrameInfo& stages = snapshot.stages;
  out_ << fmt::format("{},{:.9f},{},{},{:.9f},{:.9f},{:.9f},{:.3f},{:.3f},{:.9f},{:.9f},{:.9f},{},{:.6f},{:.6f},"
                      "{:.3f},{:.3f},{:.3f},{},{},{},{}\n",
                      frame.index, frame.timestamp_s, csv_number_or_blank(frame.exposure_ms),
                      csv_number_or_blank(frame.illuminator_power_w ? frame.illuminator_power_w
                                                                : snapshot.illuminator_power_w),
                      q.entropy_bits, q.saturated_fraction, q.black_fraction, snapshot.timings.read_ms,
                      snapshot.timings.quality_ms, q.mean, q.rms_contrast, st.gradient_energy, st.feature_count,
                      st.coverage, st.evenness, snapshot.timings.photometric_ms, snapshot.timings.odometry_ms,
                      snapshot.timings.mapping_ms, csv_number_or_blank(stages.exposure_estimate), stages.tracking,
                      stages.keyframe ? 1 : 0, stages.tracking.empty() ? std::string() : fmt::format("{:.3f}", stages.residual_rms))
       << std::flush;
  check("cannot write");
  ++rows_;
}

void MetricsCsvWriter::check(const char* what) {
  if (out_) return;
  const int error = errno;
  throw std::runtime_error(fmt::format("{}: {} ({})", path_.string(), what,
                                       error ? std::strerror(error) : "stream error"));
}

}  // namespace nirslam
