#pragma once

// Image files on disk: which files a sequence folder holds, in which order, and how they become
// grey frames. Shared by every dataset reader and by the one-off image commands.

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/core/mat.hpp>

namespace nirslam {

// "Natural" order: runs of digits compare by value, so img2 < img10 and 0009 < 10. Ties between
// equal values spelled differently (01 vs 1) fall back to plain character order, keeping the
// order strict and deterministic.
bool natural_less(std::string_view a, std::string_view b);

// Whether a file name has an extension image_codec decodes: png jpg jpeg pgm ppm pnm (any case).
// BMP and TIFF are not among them: they would need OpenCV's imgcodecs and with it GDAL.
bool is_image_file_name(const std::filesystem::path& name);

// The regular image files directly inside `folder`, in natural order of their file names.
// Throws InputError if the folder cannot be listed.
std::vector<std::filesystem::path> list_image_files(const std::filesystem::path& folder);

// Decodes image files of one sequence into grey Frame images and holds them to one size and one
// depth. 8-bit files stay CV_8UC1 (bit depth 8), 16-bit files stay CV_16UC1 (bit depth 16);
// colour files are converted to grey with a warning logged once per decoder. Every problem
// throws InputError naming the file: unreadable, undecodable, an unsupported sample type, a size
// other than the expected (or the first frame's), a depth other than the first frame's.
class GreyImageDecoder {
public:
  struct Image {
    cv::Mat image;
    int bit_depth = 8;
    bool converted_from_colour = false;
  };

  // Every image must have this size; `origin` names where the size came from ("camera.txt").
  void expect_size(int width, int height, std::string origin);

  Image read_file(const std::filesystem::path& file);
  // Encoded bytes (e.g. a zip member); `name` names them in errors.
  Image decode(const std::vector<unsigned char>& bytes, const std::filesystem::path& name);

private:
  friend Image read_grey_image(const std::filesystem::path& file);
  Image to_grey(cv::Mat decoded, const std::filesystem::path& name);

  std::optional<cv::Size> expected_size_;
  std::string expected_size_origin_;
  std::optional<int> first_depth_;
  bool warned_colour_ = false;
};

// One image file as a grey image (for commands that look at single images); same rules and
// errors as GreyImageDecoder, but no warning for colour: the caller reports converted_from_colour.
GreyImageDecoder::Image read_grey_image(const std::filesystem::path& file);

}  // namespace nirslam
