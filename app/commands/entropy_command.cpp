#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "commands/subcommand.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/image/image_files.hpp"
#include "nirslam/quality/image_quality.hpp"

namespace nirslam::app {
namespace {

struct EntropyOptions {
  std::vector<std::string> images;
  int bit_depth = 0;  // 0: from the file (8 or 16)
  bool csv = false;
};

int run_entropy(const EntropyOptions& options) {
  int failures = 0;
  if (options.csv)
    std::printf("file,width,height,bit_depth,entropy_bits,saturated_fraction,black_fraction,converted_from_colour\n");
  else
    std::printf("%13s %11s %9s %10s %5s  %s\n", "entropy[bit]", "saturated%", "black%", "size", "bits",
                "image");
  for (const std::string& file : options.images) {
    GreyImageDecoder::Image grey;
    try {
      grey = read_grey_image(file);
    } catch (const InputError& e) {
      spdlog::error("{}", e.what());
      ++failures;
      continue;
    }
    const int bit_depth = grey.bit_depth == 8 ? 8 : (options.bit_depth > 0 ? options.bit_depth : 16);
    if (grey.bit_depth == 8 && options.bit_depth > 0)
      spdlog::warn("{}: 8-bit file, --bit-depth {} ignored", file, options.bit_depth);
    const cv::Mat& image = grey.image;
    const ImageQuality q = measure_quality(image, bit_depth);
    if (options.csv) {
      std::printf("%s,%d,%d,%d,%.9f,%.9f,%.9f,%d\n", file.c_str(), image.cols, image.rows, bit_depth,
                  q.entropy_bits, q.saturated_fraction, q.black_fraction, grey.converted_from_colour ? 1 : 0);
    } else {
      const std::string size = std::to_string(image.cols) + "x" + std::to_string(image.rows);
      std::printf("%13.6f %11.3f %9.3f %10s %5d  %s%s\n", q.entropy_bits, 100.0 * q.saturated_fraction,
                  100.0 * q.black_fraction, size.c_str(), bit_depth, file.c_str(),
                  grey.converted_from_colour ? "  (colour, measured as grey)" : "");
    }
  }
  return failures == 0 ? 0 : 1;
}

}  // namespace

void add_entropy_command(CLI::App& parent, CommandAction& action) {
  auto options = std::make_shared<EntropyOptions>();
  CLI::App* cmd = parent.add_subcommand(
      "entropy",
      "Print each image's information entropy (bits, paper Eq. 2-1, 256 bins: the more, the more usable "
      "detail) and its shares of saturated and black pixels");
  cmd->add_option("images", options->images, "Image files (PNG, JPEG, binary PGM/PPM; 8 or 16 bit)")->required();
  cmd->add_option("--bit-depth", options->bit_depth,
                  "Significant bits of 16-bit files (10 for Y10, 12 for Y12); default: 16")
      ->check(CLI::Range(9, 16));
  cmd->add_flag("--csv", options->csv, "Comma-separated output with 9 decimals");
  cmd->callback([options, &action] { action = [options] { return run_entropy(*options); }; });
}

}  // namespace nirslam::app
