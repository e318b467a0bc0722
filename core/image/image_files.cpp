#include "nirslam/image/image_files.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <fstream>
#include <iterator>
#include <system_error>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "nirslam/common/error.hpp"
#include "nirslam/common/text_fields.hpp"
#include "nirslam/image/image_codec.hpp"

namespace nirslam {

namespace fs = std::filesystem;

namespace {

bool is_digit(char c) { return c >= '0' && c <= '9'; }

std::string size_text(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

}  // namespace

bool natural_less(std::string_view a, std::string_view b) {
  std::size_t i = 0;
  std::size_t j = 0;
  while (i < a.size() && j < b.size()) {
    if (is_digit(a[i]) && is_digit(b[j])) {
      // Compare the digit runs by value: without leading zeros, a longer run is a larger number.
      std::size_t end_a = i, end_b = j;
      while (end_a < a.size() && is_digit(a[end_a])) ++end_a;
      while (end_b < b.size() && is_digit(b[end_b])) ++end_b;
      std::size_t start_a = i, start_b = j;
      while (start_a + 1 < end_a && a[start_a] == '0') ++start_a;
      while (start_b + 1 < end_b && b[start_b] == '0') ++start_b;
      const std::string_view digits_a = a.substr(start_a, end_a - start_a);
      const std::string_view digits_b = b.substr(start_b, end_b - start_b);
      if (digits_a.size() != digits_b.size()) return digits_a.size() < digits_b.size();
      if (const int order = digits_a.compare(digits_b); order != 0) return order < 0;
      i = end_a;
      j = end_b;
    } else {
      if (a[i] != b[j]) return static_cast<unsigned char>(a[i]) < static_cast<unsigned char>(b[j]);
      ++i;
      ++j;
    }
  }
  const std::size_t rest_a = a.size() - i;
  const std::size_t rest_b = b.size() - j;
  if (rest_a != rest_b) return rest_a < rest_b;
  return a < b;  // equal up to leading zeros: any fixed order will do
}

bool is_image_file_name(const fs::path& name) {
  static constexpr std::array<std::string_view, 6> kExtensions = {".png", ".jpg", ".jpeg", ".pgm", ".ppm", ".pnm"};
  const std::string extension = lowercase(name.extension().string());
  return std::find(kExtensions.begin(), kExtensions.end(), extension) != kExtensions.end();
}

std::vector<fs::path> list_image_files(const fs::path& folder) {
  std::error_code error;
  fs::directory_iterator it(folder, error);
  if (error) throw InputError(folder, "cannot list folder: " + error.message());
  std::vector<fs::path> files;
  for (const fs::directory_entry& entry : it) {
    if (entry.is_regular_file(error) && is_image_file_name(entry.path()))
      files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end(), [](const fs::path& a, const fs::path& b) {
    return natural_less(a.filename().string(), b.filename().string());
  });
  return files;
}

void GreyImageDecoder::expect_size(int width, int height, std::string origin) {
  expected_size_ = cv::Size(width, height);
  expected_size_origin_ = std::move(origin);
}

GreyImageDecoder::Image GreyImageDecoder::read_file(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    throw InputError(file, fs::exists(file) ? "cannot open image file" : "image file is missing");
  }
  std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)),
                                   std::istreambuf_iterator<char>());
  if (in.bad()) throw InputError(file, "cannot read image file");
  return decode(bytes, file);
}

GreyImageDecoder::Image GreyImageDecoder::decode(const std::vector<unsigned char>& bytes,
                                                 const fs::path& name) {
  if (bytes.empty()) throw InputError(name, "image file is empty");
  cv::Mat decoded;
  try {
    decoded = decode_image(bytes);
  } catch (const std::runtime_error& error) {
    throw InputError(name, std::string("cannot decode image: ") + error.what());
  }
  return to_grey(std::move(decoded), name);
}

GreyImageDecoder::Image GreyImageDecoder::to_grey(cv::Mat decoded, const fs::path& name) {
  if (decoded.depth() != CV_8U && decoded.depth() != CV_16U)
    throw InputError(name, "unsupported sample type: only 8- and 16-bit integer images are read");
  cv::Mat grey;
  switch (decoded.channels()) {
    case 1: grey = std::move(decoded); break;
    case 2: cv::extractChannel(decoded, grey, 0); break;  // grey + alpha
    case 3: cv::cvtColor(decoded, grey, cv::COLOR_BGR2GRAY); break;
    case 4: cv::cvtColor(decoded, grey, cv::COLOR_BGRA2GRAY); break;
    default:
      throw InputError(name, "unsupported image with " + std::to_string(decoded.channels()) +
                                 " channels");
  }
  const bool converted_from_colour = decoded.channels() > 1;
  if (converted_from_colour && !warned_colour_) {
    // Once per sequence: a NIR camera should deliver grey frames, so say it, but do not flood.
    spdlog::warn("{}: colour image converted to grey (further colour frames convert silently)",
                 name.string());
    warned_colour_ = true;
  }

  const int bit_depth = grey.depth() == CV_16U ? 16 : 8;
  if (first_depth_ && *first_depth_ != bit_depth)
    throw InputError(name, "is a " + std::to_string(bit_depth) + "-bit image, but the sequence's "
                               "first frame is " + std::to_string(*first_depth_) + "-bit");
  if (expected_size_ && grey.size() != *expected_size_)
    throw InputError(name, "image is " + size_text(grey.cols, grey.rows) + " but " +
                               expected_size_origin_ + " says " +
                               size_text(expected_size_->width, expected_size_->height));
  if (!first_depth_) first_depth_ = bit_depth;
  if (!expected_size_) expect_size(grey.cols, grey.rows, "the first frame (" + name.string() + ")");
  return Image{grey, bit_depth, converted_from_colour};
}

GreyImageDecoder::Image read_grey_image(const fs::path& file) {
  GreyImageDecoder decoder;
  decoder.warned_colour_ = true;
  return decoder.read_file(file);
}

}  // namespace nirslam
