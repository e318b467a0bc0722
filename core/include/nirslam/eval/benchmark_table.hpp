#pragma once
// The tables `nirslam bench` writes, in the layout of the paper's Table 2: one row per sequence
// ("Room_20", ..., "Tunnel_100"), one ATE column per pipeline mode, and the improvement of the
// last mode over the one before in percent; then frames per second and peak memory per run.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace nirslam {

struct BenchmarkRun {
  std::string sequence;               // "Room_20"
  std::string mode;                   // "odometry", "calibrated", ...
  std::optional<double> ate_rmse_m;   // after Sim(3) alignment; empty: no ground truth, or no pose
  double path_length_m = 0.0;         // ground truth, over the evaluated poses
  int segments = 0;                   // 1 = tracked throughout; more: lost and re-initialised
  int keyframes = 0;                  // the odometry's, over the whole run (0: it did not run)
  double tracked_fraction = 0.0;      // frames with a pose in the evaluated segment / frames
  double frames_per_second = 0.0;
  double peak_memory_mib = 0.0;
  std::string note;                   // why there is no ATE, or what to know about it
  // ATE as a percentage of the path length (the 1 % target); empty without both.
  std::optional<double> ate_percent_of_path() const;
};

struct BenchmarkTable {
  std::vector<std::string> modes;      // column order
  std::vector<std::string> sequences;  // row order
  std::vector<BenchmarkRun> runs;
  const BenchmarkRun* find(const std::string& sequence, const std::string& mode) const;
};

// Improvement of `after` over `before` in percent: (before - after) / before * 100 (positive =
// lower ATE). Empty when either is missing or before is 0.
std::optional<double> improvement_percent(const std::optional<double>& before, const std::optional<double>& after);

// The Markdown table (with a legend line under it).
std::string benchmark_markdown(const BenchmarkTable& table);
// The same figures as CSV, one row per sequence. Throws std::runtime_error naming the file.
void write_benchmark_csv(const std::filesystem::path& file, const BenchmarkTable& table);

}  // namespace nirslam
