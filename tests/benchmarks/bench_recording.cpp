// Session recording (issue 11): can the recorder keep up with a 640x480 camera at 30 fps on one
// core? Run `build/nirslam_benchmarks --benchmark_filter=Record|Encode`; items_per_second is
// frames per second. BM_EncodeFrame is the CPU part alone (PNG level as the second argument, -1 for
// raw PGM; third argument 1 for Huffman-only coding, the recorder's default); BM_RecordFrames the whole path on the build machine's disk: encode, write to a temp
// name, fsync, rename, fsync the folder, append and fdatasync the journal line.
#include <filesystem>
#include <vector>

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>

#include "nirslam/image/image_codec.hpp"
#include "nirslam/session/session_recorder.hpp"
#include "nirslam/sources/demo_source.hpp"

namespace {

namespace fs = std::filesystem;

// Realistic content: the demo's textured wall with sensor noise (noise-free frames would flatter
// PNG). 16 bit: the same scene at 12 significant bits, with the noise in the low bits.
const std::vector<nirslam::Frame>& frames(int bit_depth) {
  static const std::vector<nirslam::Frame> eight = [] {
    std::vector<nirslam::Frame> out;
    auto source = nirslam::make_demo_source();
    for (int i = 0; i < 30; ++i) out.push_back(*source->next());
    return out;
  }();
  static const std::vector<nirslam::Frame> sixteen = [] {
    std::vector<nirslam::Frame> out;
    cv::RNG rng(7);
    for (const nirslam::Frame& f : eight) {
      nirslam::Frame g = f;
      cv::Mat noise(f.image.size(), CV_16UC1);
      rng.fill(noise, cv::RNG::UNIFORM, 0, 16);
      f.image.convertTo(g.image, CV_16UC1, 16.0);
      g.image += noise;
      g.bit_depth = 12;
      out.push_back(g);
    }
    return out;
  }();
  return bit_depth > 8 ? sixteen : eight;
}

void BM_EncodeFrame(benchmark::State& state) {
  const auto& input = frames(static_cast<int>(state.range(0)));
  const int level = static_cast<int>(state.range(1));
  const nirslam::PngStrategy strategy = state.range(2) != 0 ? nirslam::PngStrategy::HuffmanOnly : nirslam::PngStrategy::Default;
  std::size_t i = 0, bytes = 0;
  std::vector<unsigned char> encoded;
  for (auto _ : state) {
    const cv::Mat& image = input[i++ % input.size()].image;
    encoded = level < 0 ? nirslam::encode_pnm(image) : nirslam::encode_png(image, {.compression_level = level, .strategy = strategy});
    bytes += encoded.size();
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["KiB_per_frame"] = static_cast<double>(bytes) / 1024.0 / static_cast<double>(state.iterations());
}
BENCHMARK(BM_EncodeFrame)
    ->ArgNames({"bits", "png_level", "huffman_only"})
    ->Args({8, -1, 0})->Args({8, 0, 0})->Args({8, 1, 0})->Args({8, 3, 0})->Args({8, 6, 0})->Args({8, 1, 1})->Args({8, 6, 1})
    ->Args({16, -1, 0})->Args({16, 0, 0})->Args({16, 1, 0})->Args({16, 3, 0})->Args({16, 6, 0})->Args({16, 1, 1})->Args({16, 6, 1})
    ->Unit(benchmark::kMillisecond);

// One second of video (30 frames) per iteration through a fresh recorder, until stop() returns.
void BM_RecordFrames(benchmark::State& state) {
  const auto& input = frames(static_cast<int>(state.range(0)));
  nirslam::RecorderOptions options;
  options.min_free_bytes_to_start = 0;
  options.min_free_bytes_while_recording = 0;
  options.format = state.range(1) < 0 ? nirslam::FrameFileFormat::Pgm : nirslam::FrameFileFormat::Png;
  options.png_compression = state.range(1) < 0 ? 1 : static_cast<int>(state.range(1));
  options.png_huffman_only = state.range(2) != 0;
  const fs::path root = fs::temp_directory_path() / "nirslam_bench_recording";
  std::int64_t dropped = 0;
  int run = 0;
  for (auto _ : state) {
    state.PauseTiming();
    fs::remove_all(root);
    auto recorder = std::make_unique<nirslam::SessionRecorder>(root / std::to_string(run++),
                                                               nirslam::RecordingSourceInfo{"bench", "demo", 30.0, nullptr}, options);
    state.ResumeTiming();
    for (const nirslam::Frame& frame : input) recorder->record(frame);
    dropped += recorder->stop("done").frames_dropped;
  }
  fs::remove_all(root);
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(input.size()));
  state.counters["dropped"] = static_cast<double>(dropped);
}
BENCHMARK(BM_RecordFrames)
    ->ArgNames({"bits", "png_level", "huffman_only"})
    ->Args({8, -1, 0})->Args({8, 1, 0})->Args({8, 1, 1})->Args({16, -1, 0})->Args({16, 1, 0})->Args({16, 1, 1})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
