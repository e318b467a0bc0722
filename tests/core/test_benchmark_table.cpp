// The bench tables: the paper's Table 2 layout, the improvement column, runs without an ATE, and
// the CSV with the same figures.

#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "nirslam/eval/benchmark_table.hpp"

namespace nirslam {
namespace {

BenchmarkTable two_mode_table() {
  BenchmarkTable table;
  table.modes = {"odometry", "calibrated"};
  table.sequences = {"Room_20", "Tunnel_100"};
  BenchmarkRun a{"Room_20", "odometry", 0.10, 5.0, 1, 74, 1.0, 25.0, 120.0, ""};
  BenchmarkRun b{"Room_20", "calibrated", 0.08, 5.0, 1, 71, 1.0, 22.0, 140.0, ""};
  BenchmarkRun c{"Tunnel_100", "odometry", std::nullopt, 0.0, 0, 0, 0.0, 24.0, 110.0, "no pose"};
  BenchmarkRun d{"Tunnel_100", "calibrated", 0.30, 10.0, 2, 90, 0.7, 21.0, 130.0, ""};
  table.runs = {a, b, c, d};
  return table;
}

TEST(BenchmarkTable, ImprovementIsTheLowerAteInPercentOfTheModeBefore) {
  EXPECT_NEAR(*improvement_percent(0.10, 0.08), 20.0, 1e-9);
  EXPECT_NEAR(*improvement_percent(0.10, 0.12), -20.0, 1e-9);
  EXPECT_FALSE(improvement_percent(std::nullopt, 0.1));
  EXPECT_FALSE(improvement_percent(0.0, 0.1));
}

TEST(BenchmarkTable, MarkdownHasOneRowPerSequenceAndOneAteColumnPerMode) {
  const std::string md = benchmark_markdown(two_mode_table());
  EXPECT_NE(md.find("| Sequence | ATE odometry [m] | ATE calibrated [m] | Improvement calibrated vs odometry [%] |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("| Room_20 | 0.1000 | 0.0800 | +20.0 | 1.60 | 25.0 | 22.0 | 140 |"), std::string::npos) << md;
  // A run without an ATE says why; a run that lost tracking says how many segments it had.
  EXPECT_NE(md.find("| Tunnel_100 | n/a (no pose) | 0.3000 (2 segments) | – | 3.00 |"), std::string::npos) << md;
}

TEST(BenchmarkTable, CsvCarriesTheSameFigures) {
  const auto file = std::filesystem::temp_directory_path() / "nirslam_bench_table.csv";
  write_benchmark_csv(file, two_mode_table());
  std::ifstream in(file);
  std::string header;
  std::string room;
  std::string tunnel;
  std::getline(in, header);
  std::getline(in, room);
  std::getline(in, tunnel);
  EXPECT_EQ(header.rfind("sequence,ate_m_odometry,segments_odometry,keyframes_odometry,tracked_fraction_odometry,", 0), 0u)
      << header;
  EXPECT_EQ(room, "Room_20,0.100000,1,74,1.0000,25.00,120.0,0.080000,1,71,1.0000,22.00,140.0,5.0000,20.00");
  EXPECT_EQ(tunnel.rfind("Tunnel_100,,0,0,0.0000,24.00,110.0,0.300000,2,90,0.7000,", 0), 0u) << tunnel;
  std::filesystem::remove(file);
}

TEST(BenchmarkTable, UnwritableCsvNamesTheFile) {
  try {
    write_benchmark_csv("/no/such/folder/bench.csv", two_mode_table());
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/no/such/folder/bench.csv"), std::string::npos);
  }
}

}  // namespace
}  // namespace nirslam
