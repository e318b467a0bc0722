#include "nirslam/eval/benchmark_table.hpp"

#include <algorithm>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>

namespace nirslam {
namespace {

std::string ate_cell(const BenchmarkRun* run) {
  if (run == nullptr) return "–";
  if (!run->ate_rmse_m) return run->note.empty() ? "n/a" : "n/a (" + run->note + ")";
  std::string cell = fmt::format("{:.4f}", *run->ate_rmse_m);
  if (run->segments > 1) cell += fmt::format(" ({} segments)", run->segments);
  return cell;
}

std::string formatted_or_blank(const std::optional<double>& value, const char* format) {
  return value ? fmt::format(fmt::runtime(format), *value) : std::string();
}

}  // namespace

std::optional<double> BenchmarkRun::ate_percent_of_path() const {
  if (!ate_rmse_m || path_length_m <= 0.0) return std::nullopt;
  return 100.0 * *ate_rmse_m / path_length_m;
}

const BenchmarkRun* BenchmarkTable::find(const std::string& sequence, const std::string& mode) const {
  for (const BenchmarkRun& run : runs)
    if (run.sequence == sequence && run.mode == mode) return &run;
  return nullptr;
}

std::optional<double> improvement_percent(const std::optional<double>& before, const std::optional<double>& after) {
  if (!before || !after || *before <= 0.0) return std::nullopt;
  return (*before - *after) / *before * 100.0;
}

std::string benchmark_markdown(const BenchmarkTable& table) {
  std::ostringstream out;
  const bool compare = table.modes.size() >= 2;
  const std::string& last = table.modes.empty() ? std::string() : table.modes.back();
  const std::string& previous = compare ? table.modes[table.modes.size() - 2] : std::string();

  out << "| Sequence |";
  for (const std::string& mode : table.modes) out << " ATE " << mode << " [m] |";
  if (compare) out << " Improvement " << last << " vs " << previous << " [%] |";
  out << " ATE / path [%] |";
  for (const std::string& mode : table.modes) out << " fps " << mode << " |";
  out << " Peak memory [MiB] |\n|---|";
  for (std::size_t i = 0; i < table.modes.size(); ++i) out << "---:|";
  if (compare) out << "---:|";
  out << "---:|";
  for (std::size_t i = 0; i < table.modes.size(); ++i) out << "---:|";
  out << "---:|\n";

  for (const std::string& sequence : table.sequences) {
    out << "| " << sequence << " |";
    for (const std::string& mode : table.modes) out << ' ' << ate_cell(table.find(sequence, mode)) << " |";
    const BenchmarkRun* last_run = table.find(sequence, last);
    if (compare) {
      const BenchmarkRun* previous_run = table.find(sequence, previous);
      const auto gain = improvement_percent(previous_run ? previous_run->ate_rmse_m : std::nullopt,
                                            last_run ? last_run->ate_rmse_m : std::nullopt);
      out << ' ' << (gain ? fmt::format("{:+.1f}", *gain) : "–") << " |";
    }
    const auto percent = last_run ? last_run->ate_percent_of_path() : std::nullopt;
    out << ' ' << (percent ? fmt::format("{:.2f}", *percent) : "–") << " |";
    double peak = 0.0;
    for (const std::string& mode : table.modes) {
      const BenchmarkRun* run = table.find(sequence, mode);
      out << ' ' << (run ? fmt::format("{:.1f}", run->frames_per_second) : "–") << " |";
      if (run) peak = std::max(peak, run->peak_memory_mib);
    }
    out << ' ' << fmt::format("{:.0f}", peak) << " |\n";
  }
  out << "\nATE: RMSE of the camera positions after Sim(3) alignment to the ground truth, in metres"
         " (a run that lost tracking is evaluated on its longest segment and says so). "
         "Improvement: lower ATE of the last mode in percent of the one before. "
         "ATE / path: the last mode's ATE over the ground-truth path length.\n";
  return out.str();
}

void write_benchmark_csv(const std::filesystem::path& file, const BenchmarkTable& table) {
  std::ofstream out(file, std::ios::trunc);
  if (!out) throw std::runtime_error(file.string() + ": cannot open for writing");
  out << "sequence";
  for (const std::string& mode : table.modes)
    out << ",ate_m_" << mode << ",segments_" << mode << ",keyframes_" << mode << ",tracked_fraction_" << mode
        << ",fps_" << mode << ",peak_memory_mib_" << mode;
  out << ",path_length_m,improvement_percent\n";
  for (const std::string& sequence : table.sequences) {
    out << sequence;
    double path = 0.0;
    for (const std::string& mode : table.modes) {
      const BenchmarkRun* run = table.find(sequence, mode);
      if (run == nullptr) {
        out << ",,,,,,";
        continue;
      }
      path = std::max(path, run->path_length_m);
      out << ',' << formatted_or_blank(run->ate_rmse_m, "{:.6f}") << ',' << run->segments << ',' << run->keyframes << ','
          << fmt::format("{:.4f}", run->tracked_fraction) << ',' << fmt::format("{:.2f}", run->frames_per_second) << ','
          << fmt::format("{:.1f}", run->peak_memory_mib);
    }
    std::optional<double> gain;
    if (table.modes.size() >= 2) {
      const BenchmarkRun* a = table.find(sequence, table.modes[table.modes.size() - 2]);
      const BenchmarkRun* b = table.find(sequence, table.modes.back());
      gain = improvement_percent(a ? a->ate_rmse_m : std::nullopt, b ? b->ate_rmse_m : std::nullopt);
    }
    out << ',' << fmt::format("{:.4f}", path) << ',' << formatted_or_blank(gain, "{:.2f}") << '\n';
  }
  out.flush();
  if (!out) throw std::runtime_error(file.string() + ": write failed (disk full?)");
}

}  // namespace nirslam
