#include "nirslam/image/image_codec.hpp"

#include <bit>
#include <cerrno>
#include <csetjmp>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <new>
#include <stdexcept>
#include <string>
#include <system_error>

// jpeglib.h uses FILE and size_t without including their headers.
#include <jpeglib.h>
#include <jerror.h>
#include <png.h>
#include <zlib.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "nirslam/common/error.hpp"
#include "nirslam/common/text_fields.hpp"

namespace nirslam {

namespace fs = std::filesystem;

namespace {

// A corrupt header must not turn into a multi-gigabyte allocation.
constexpr std::size_t kMaxImageBytes = std::size_t{1} << 31;
constexpr unsigned kMaxSide = 1u << 20;

constexpr bool kLittleEndian = std::endian::native == std::endian::little;

bool has_prefix(std::span<const std::uint8_t> bytes, std::string_view prefix) {
  return bytes.size() >= prefix.size() && std::memcmp(bytes.data(), prefix.data(), prefix.size()) == 0;
}

void check_size(unsigned width, unsigned height, int channels, int bytes_per_sample) {
  if (width == 0 || height == 0) throw std::runtime_error("the header says the image is empty");
  if (width > kMaxSide || height > kMaxSide ||
      std::size_t{width} * height * static_cast<std::size_t>(channels * bytes_per_sample) > kMaxImageBytes)
    throw std::runtime_error("the header's size " + std::to_string(width) + "x" + std::to_string(height) +
                             " is implausibly large");
}

std::string describe_type(const cv::Mat& image) { return cv::typeToString(image.type()); }

// ---------------------------------------------------------------------------------------------
// libpng and libjpeg report errors through a callback that must not return. The callbacks below
// longjmp back into the one function that called the library (run_png_decode and friends); those
// functions keep no locals with destructors and write only into a state object owned by their
// caller, so the jump skips no destructor and loses nothing. The state's destructor releases the
// library's structures on every path, including C++ exceptions (allocation) thrown between
// library calls.

struct PngInput {
  const std::uint8_t* data = nullptr;
  std::size_t size = 0;
  std::size_t offset = 0;
};

struct PngDecodeState {
  png_structp png = nullptr;
  png_infop info = nullptr;
  PngInput input;
  char error[200] = "";
  cv::Mat image;
  std::vector<png_bytep> rows;
  ~PngDecodeState() { png_destroy_read_struct(&png, info ? &info : nullptr, nullptr); }
};

struct PngEncodeState {
  png_structp png = nullptr;
  png_infop info = nullptr;
  std::vector<std::uint8_t> bytes;
  char error[200] = "";
  std::vector<png_bytep> rows;
  ~PngEncodeState() { png_destroy_write_struct(&png, info ? &info : nullptr); }
};

template <typename State>
void png_fail(png_structp png, png_const_charp message) {
  auto* state = static_cast<State*>(png_get_error_ptr(png));
  std::snprintf(state->error, sizeof state->error, "%s", message);
  png_longjmp(png, 1);
}

// libpng warns about harmless things (e.g. "known incorrect sRGB profile"): not the operator's
// concern, and a library must not write to stderr on its own.
void png_ignore_warning(png_structp, png_const_charp) {}

void png_read_from_memory(png_structp png, png_bytep out, std::size_t length) {
  auto* input = static_cast<PngInput*>(png_get_io_ptr(png));
  if (length > input->size - input->offset) png_error(png, "truncated PNG data");
  std::memcpy(out, input->data + input->offset, length);
  input->offset += length;
}

void png_append_to_vector(png_structp png, png_bytep data, std::size_t length) {
  auto* state = static_cast<PngEncodeState*>(png_get_io_ptr(png));
  bool out_of_memory = false;
  try {
    state->bytes.insert(state->bytes.end(), data, data + length);
  } catch (const std::bad_alloc&) {
    out_of_memory = true;  // png_error longjmps: not from inside the catch block
  }
  if (out_of_memory) png_error(png, "out of memory");
}

void png_no_flush(png_structp) {}

bool run_png_decode(PngDecodeState& s) {
  if (setjmp(png_jmpbuf(s.png))) return false;
  png_set_read_fn(s.png, &s.input, png_read_from_memory);
  png_read_info(s.png, s.info);
  const int color_type = png_get_color_type(s.png, s.info);
  const int file_depth = png_get_bit_depth(s.png, s.info);
  if (color_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(s.png);
  if (color_type == PNG_COLOR_TYPE_GRAY && file_depth < 8) png_set_expand_gray_1_2_4_to_8(s.png);
  if (png_get_valid(s.png, s.info, PNG_INFO_tRNS)) png_set_tRNS_to_alpha(s.png);
  if (file_depth == 16 && kLittleEndian) png_set_swap(s.png);
  png_set_bgr(s.png);
  png_set_interlace_handling(s.png);
  png_read_update_info(s.png, s.info);

  const png_uint_32 width = png_get_image_width(s.png, s.info);
  const png_uint_32 height = png_get_image_height(s.png, s.info);
  const int channels = png_get_channels(s.png, s.info);
  const int depth = png_get_bit_depth(s.png, s.info);
  check_size(width, height, channels, depth == 16 ? 2 : 1);
  s.image.create(static_cast<int>(height), static_cast<int>(width), CV_MAKETYPE(depth == 16 ? CV_16U : CV_8U, channels));
  if (png_get_rowbytes(s.png, s.info) != s.image.step[0]) png_error(s.png, "unexpected row layout after expansion");
  s.rows.resize(height);
  for (png_uint_32 y = 0; y < height; ++y) s.rows[y] = s.image.ptr(static_cast<int>(y));
  png_read_image(s.png, s.rows.data());
  png_read_end(s.png, nullptr);
  return true;
}

cv::Mat decode_png(std::span<const std::uint8_t> bytes) {
  PngDecodeState s;
  s.input = {bytes.data(), bytes.size(), 0};
  s.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &s, png_fail<PngDecodeState>, png_ignore_warning);
  if (s.png == nullptr) throw std::bad_alloc();
  s.info = png_create_info_struct(s.png);
  if (s.info == nullptr) throw std::bad_alloc();
  if (!run_png_decode(s)) throw std::runtime_error(std::string("corrupt PNG: ") + s.error);
  return std::move(s.image);
}

bool run_png_encode(PngEncodeState& s, const cv::Mat& image, const PngOptions& options) {
  if (setjmp(png_jmpbuf(s.png))) return false;
  png_set_write_fn(s.png, &s, png_append_to_vector, png_no_flush);
  const int channels = image.channels();
  const int color_type = channels == 1 ? PNG_COLOR_TYPE_GRAY : channels == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_RGB_ALPHA;
  const int depth = image.depth() == CV_16U ? 16 : 8;
  png_set_IHDR(s.png, s.info, static_cast<png_uint_32>(image.cols), static_cast<png_uint_32>(image.rows), depth,
               color_type, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_compression_level(s.png, options.compression_level);
  png_set_compression_strategy(s.png, options.strategy == PngStrategy::HuffmanOnly ? Z_HUFFMAN_ONLY : Z_DEFAULT_STRATEGY);
  png_write_info(s.png, s.info);
  png_set_bgr(s.png);
  if (depth == 16 && kLittleEndian) png_set_swap(s.png);
  png_write_image(s.png, s.rows.data());
  png_write_end(s.png, nullptr);
  return true;
}

// ---------------------------------------------------------------------------------------------

struct JpegErrors {
  jpeg_error_mgr base;  // first: libjpeg hands callbacks a pointer to it
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX];
};

void jpeg_fail(j_common_ptr info) {
  auto* errors = reinterpret_cast<JpegErrors*>(info->err);
  (*info->err->format_message)(info, errors->message);
  std::longjmp(errors->jump, 1);
}

// libjpeg treats a stream that ends early as a warning and pads the picture with grey; a frame
// that is partly made up is an error here. Other warnings (extra bytes between markers, common
// from UVC cameras) are counted silently.
void jpeg_message(j_common_ptr info, int level) {
  if (level >= 0) return;  // trace messages
  const int code = info->err->msg_code;
  if (code == JWRN_JPEG_EOF || code == JWRN_HIT_MARKER) jpeg_fail(info);
  ++info->err->num_warnings;
}

void jpeg_install_errors(JpegErrors& errors) {
  jpeg_std_error(&errors.base);
  errors.base.error_exit = jpeg_fail;
  errors.base.emit_message = jpeg_message;
  errors.message[0] = '\0';
}

struct JpegDecodeState {
  jpeg_decompress_struct info{};
  JpegErrors errors{};
  cv::Mat image;
  // jpeg_destroy_* is a no-op on a zeroed struct, so this is safe whatever stage failed.
  ~JpegDecodeState() { jpeg_destroy_decompress(&info); }
};

bool run_jpeg_decode(JpegDecodeState& s, std::span<const std::uint8_t> bytes, ImageReadMode mode) {
  if (setjmp(s.errors.jump)) return false;
  jpeg_create_decompress(&s.info);
  jpeg_mem_src(&s.info, bytes.data(), static_cast<unsigned long>(bytes.size()));
  jpeg_read_header(&s.info, TRUE);
  if (s.info.jpeg_color_space == JCS_CMYK || s.info.jpeg_color_space == JCS_YCCK) {
    std::snprintf(s.errors.message, sizeof s.errors.message, "CMYK JPEG is not supported");
    return false;
  }
  // A grey file read as stored stays one channel, as OpenCV's unchanged read kept it.
  const bool grey = mode == ImageReadMode::Grey || (mode == ImageReadMode::AsStored && s.info.num_components == 1);
  s.info.out_color_space = grey ? JCS_GRAYSCALE : JCS_EXT_BGR;
  jpeg_start_decompress(&s.info);
  check_size(s.info.output_width, s.info.output_height, s.info.output_components, 1);
  s.image.create(static_cast<int>(s.info.output_height), static_cast<int>(s.info.output_width),
                 CV_8UC(s.info.output_components));
  while (s.info.output_scanline < s.info.output_height) {
    JSAMPROW row = s.image.ptr(static_cast<int>(s.info.output_scanline));
    jpeg_read_scanlines(&s.info, &row, 1);
  }
  jpeg_finish_decompress(&s.info);
  return true;
}

cv::Mat decode_jpeg(std::span<const std::uint8_t> bytes, ImageReadMode mode) {
  JpegDecodeState s;
  s.info.err = &s.errors.base;
  jpeg_install_errors(s.errors);
  if (!run_jpeg_decode(s, bytes, mode)) throw std::runtime_error(std::string("corrupt JPEG: ") + s.errors.message);
  return std::move(s.image);
}

// ---------------------------------------------------------------------------------------------

bool is_pnm_space(std::uint8_t c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f'; }

// One header number; whitespace and '#' comments may come before it, as netpbm allows.
unsigned pnm_header_number(std::span<const std::uint8_t> bytes, std::size_t& pos) {
  while (pos < bytes.size() && (is_pnm_space(bytes[pos]) || bytes[pos] == '#')) {
    if (bytes[pos] == '#') {
      while (pos < bytes.size() && bytes[pos] != '\n') ++pos;
    } else {
      ++pos;
    }
  }
  if (pos >= bytes.size() || bytes[pos] < '0' || bytes[pos] > '9')
    throw std::runtime_error("PGM/PPM header is truncated or malformed");
  unsigned value = 0;
  while (pos < bytes.size() && bytes[pos] >= '0' && bytes[pos] <= '9') {
    value = value * 10 + static_cast<unsigned>(bytes[pos] - '0');
    if (value > kMaxSide) throw std::runtime_error("PGM/PPM header number is implausibly large");
    ++pos;
  }
  return value;
}

cv::Mat decode_pnm(std::span<const std::uint8_t> bytes) {
  const std::uint8_t kind = bytes[1];
  if (kind == '1' || kind == '2' || kind == '3' || kind == '4')
    throw std::runtime_error("plain (ASCII) or bitmap PNM is not supported, only binary PGM (P5) and PPM (P6)");
  std::size_t pos = 2;
  const unsigned width = pnm_header_number(bytes, pos);
  const unsigned height = pnm_header_number(bytes, pos);
  const unsigned max_value = pnm_header_number(bytes, pos);
  if (max_value == 0 || max_value > 65535) throw std::runtime_error("PGM/PPM maximum value must be 1-65535");
  if (pos >= bytes.size() || !is_pnm_space(bytes[pos])) throw std::runtime_error("PGM/PPM header is truncated or malformed");
  ++pos;  // exactly one whitespace character before the samples
  const int channels = kind == '5' ? 1 : 3;
  const bool wide = max_value > 255;
  check_size(width, height, channels, wide ? 2 : 1);
  cv::Mat image(static_cast<int>(height), static_cast<int>(width), CV_MAKETYPE(wide ? CV_16U : CV_8U, channels));
  const std::size_t needed = image.total() * image.elemSize();
  if (bytes.size() - pos < needed)
    throw std::runtime_error("truncated PGM/PPM data (" + std::to_string(bytes.size() - pos) + " of " +
                             std::to_string(needed) + " sample bytes)");
  const std::uint8_t* in = bytes.data() + pos;
  if (wide) {
    auto* out = image.ptr<std::uint16_t>();
    for (std::size_t i = 0; i < needed / 2; ++i)
      out[i] = static_cast<std::uint16_t>((in[2 * i] << 8) | in[2 * i + 1]);  // big-endian in the file
  } else {
    std::memcpy(image.data, in, needed);
  }
  if (channels == 3) cv::cvtColor(image, image, cv::COLOR_RGB2BGR);
  return image;
}

// ---------------------------------------------------------------------------------------------

cv::Mat high_byte(const cv::Mat& image) {
  if (image.depth() != CV_16U) return image;
  cv::Mat out(image.size(), CV_MAKETYPE(CV_8U, image.channels()));
  for (int y = 0; y < image.rows; ++y) {
    const auto* in = image.ptr<std::uint16_t>(y);
    std::uint8_t* o = out.ptr(y);
    for (int x = 0; x < image.cols * image.channels(); ++x) o[x] = static_cast<std::uint8_t>(in[x] >> 8);
  }
  return out;
}

cv::Mat first_channel_if_grey_alpha(const cv::Mat& image) {
  if (image.channels() != 2) return image;
  cv::Mat grey;
  cv::extractChannel(image, grey, 0);
  return grey;
}

cv::Mat apply_mode(cv::Mat image, ImageReadMode mode) {
  if (mode == ImageReadMode::AsStored) return image;
  cv::Mat out = first_channel_if_grey_alpha(high_byte(image));
  switch (out.channels()) {
    case 1:
      if (mode == ImageReadMode::Bgr) cv::cvtColor(out, out, cv::COLOR_GRAY2BGR);
      break;
    case 3:
      if (mode == ImageReadMode::Grey) cv::cvtColor(out, out, cv::COLOR_BGR2GRAY);
      break;
    case 4: cv::cvtColor(out, out, mode == ImageReadMode::Grey ? cv::COLOR_BGRA2GRAY : cv::COLOR_BGRA2BGR); break;
    default: throw std::runtime_error("unsupported channel count " + std::to_string(out.channels()));
  }
  return out;
}

// ---------------------------------------------------------------------------------------------

struct JpegEncodeState {
  jpeg_compress_struct info{};
  JpegErrors errors{};
  unsigned char* initial = nullptr;  // ours; libjpeg allocates a larger one if this fills up
  unsigned char* buffer = nullptr;
  unsigned long size = 0;
  ~JpegEncodeState() {
    jpeg_destroy_compress(&info);
    if (buffer != initial) std::free(buffer);
    std::free(initial);
  }
};

bool run_jpeg_encode(JpegEncodeState& s, const cv::Mat& image, int quality) {
  if (setjmp(s.errors.jump)) return false;
  jpeg_create_compress(&s.info);
  jpeg_mem_dest(&s.info, &s.buffer, &s.size);
  s.info.image_width = static_cast<JDIMENSION>(image.cols);
  s.info.image_height = static_cast<JDIMENSION>(image.rows);
  s.info.input_components = image.channels();
  s.info.in_color_space = image.channels() == 1 ? JCS_GRAYSCALE : JCS_EXT_BGR;
  jpeg_set_defaults(&s.info);
  jpeg_set_quality(&s.info, quality, TRUE);
  jpeg_start_compress(&s.info, TRUE);
  while (s.info.next_scanline < s.info.image_height) {
    JSAMPROW row = const_cast<JSAMPROW>(image.ptr(static_cast<int>(s.info.next_scanline)));
    jpeg_write_scanlines(&s.info, &row, 1);
  }
  jpeg_finish_compress(&s.info);
  return true;
}

}  // namespace

cv::Mat decode_image(std::span<const std::uint8_t> bytes, ImageReadMode mode) {
  if (bytes.empty()) throw std::runtime_error("no image data (empty)");
  if (has_prefix(bytes, "\x89PNG\r\n\x1a\n")) return apply_mode(decode_png(bytes), mode);
  if (has_prefix(bytes, "\xff\xd8\xff")) return apply_mode(decode_jpeg(bytes, mode), mode);
  if (bytes.size() >= 2 && bytes[0] == 'P' && bytes[1] >= '1' && bytes[1] <= '6') return apply_mode(decode_pnm(bytes), mode);
  if (has_prefix(bytes, "BM") || has_prefix(bytes, "II*") || has_prefix(bytes, std::string_view("MM\0*", 4)))
    throw std::runtime_error("BMP and TIFF files are not supported: convert to PNG");
  throw std::runtime_error("not a PNG, JPEG or binary PGM/PPM file");
}

cv::Mat read_image(const fs::path& file, ImageReadMode mode) {
  // A folder opens as a stream on Linux and then reports a nonsense size.
  if (std::error_code error; fs::is_directory(file, error)) throw InputError(file, "is a folder, not an image file");
  std::ifstream in(file, std::ios::binary | std::ios::ate);
  if (!in) throw InputError(file, fs::exists(file) ? "cannot open image file" : "image file is missing");
  const std::streamoff size = in.tellg();
  if (size < 0) throw InputError(file, "cannot read image file");
  if (size == 0) throw InputError(file, "image file is empty");
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
  in.seekg(0);
  in.read(reinterpret_cast<char*>(bytes.data()), size);
  if (in.gcount() != size) throw InputError(file, "cannot read image file");
  try {
    return decode_image(bytes, mode);
  } catch (const std::runtime_error& e) {
    throw InputError(file, std::string("cannot decode image: ") + e.what());
  }
}

std::vector<std::uint8_t> encode_png(const cv::Mat& image, const PngOptions& options) {
  const int channels = image.channels();
  if (image.empty() || (image.depth() != CV_8U && image.depth() != CV_16U) || (channels != 1 && channels != 3 && channels != 4))
    throw std::invalid_argument("PNG holds 8- or 16-bit images with 1, 3 or 4 channels, not " +
                                (image.empty() ? std::string("an empty image") : describe_type(image)));
  if (options.compression_level < 0 || options.compression_level > 9)
    throw std::invalid_argument("PNG compression level " + std::to_string(options.compression_level) + " is not 0-9");
  PngEncodeState s;
  s.png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &s, png_fail<PngEncodeState>, png_ignore_warning);
  if (s.png == nullptr) throw std::bad_alloc();
  s.info = png_create_info_struct(s.png);
  if (s.info == nullptr) throw std::bad_alloc();
  s.bytes.reserve(image.total() * image.elemSize() / 2 + 1024);
  s.rows.resize(static_cast<std::size_t>(image.rows));
  // libpng copies each row before its transforms (BGR swap, byte swap): the image is not written.
  for (int y = 0; y < image.rows; ++y) s.rows[static_cast<std::size_t>(y)] = const_cast<png_bytep>(image.ptr(y));
  if (!run_png_encode(s, image, options)) throw std::runtime_error(std::string("PNG encoding failed: ") + s.error);
  return std::move(s.bytes);
}

std::vector<std::uint8_t> encode_pnm(const cv::Mat& image) {
  const int channels = image.channels();
  if (image.empty() || (image.depth() != CV_8U && image.depth() != CV_16U) || (channels != 1 && channels != 3))
    throw std::invalid_argument("PGM/PPM holds 8- or 16-bit images with 1 or 3 channels, not " +
                                (image.empty() ? std::string("an empty image") : describe_type(image)));
  const bool wide = image.depth() == CV_16U;
  const std::string header = std::string(channels == 1 ? "P5\n" : "P6\n") + std::to_string(image.cols) + " " +
                             std::to_string(image.rows) + "\n" + (wide ? "65535" : "255") + "\n";
  cv::Mat rgb;  // not a header onto `image`: the conversion would then overwrite the caller's pixels
  if (channels == 3)
    cv::cvtColor(image, rgb, cv::COLOR_BGR2RGB);
  else
    rgb = image;
  std::vector<std::uint8_t> bytes(header.begin(), header.end());
  const std::size_t row_bytes = static_cast<std::size_t>(image.cols) * image.elemSize();
  bytes.resize(header.size() + row_bytes * static_cast<std::size_t>(image.rows));
  std::uint8_t* out = bytes.data() + header.size();
  for (int y = 0; y < rgb.rows; ++y, out += row_bytes) {
    if (wide) {
      const auto* in = rgb.ptr<std::uint16_t>(y);
      for (std::size_t i = 0; i < row_bytes / 2; ++i) {
        out[2 * i] = static_cast<std::uint8_t>(in[i] >> 8);  // big-endian in the file
        out[2 * i + 1] = static_cast<std::uint8_t>(in[i] & 0xff);
      }
    } else {
      std::memcpy(out, rgb.ptr(y), row_bytes);
    }
  }
  return bytes;
}

std::vector<std::uint8_t> encode_jpeg(const cv::Mat& image, int quality) {
  if (image.empty() || image.depth() != CV_8U || (image.channels() != 1 && image.channels() != 3))
    throw std::invalid_argument("JPEG holds 8-bit grey or colour images, not " +
                                (image.empty() ? std::string("an empty image") : describe_type(image)));
  if (quality < 1 || quality > 100) throw std::invalid_argument("JPEG quality " + std::to_string(quality) + " is not 1-100");
  JpegEncodeState s;
  s.info.err = &s.errors.base;
  jpeg_install_errors(s.errors);
  // Our own first buffer: libjpeg then never frees it behind our back if it has to grow.
  s.size = static_cast<unsigned long>(image.total() * image.elemSize() / 2 + 4096);
  s.initial = static_cast<unsigned char*>(std::malloc(s.size));
  if (s.initial == nullptr) throw std::bad_alloc();
  s.buffer = s.initial;
  if (!run_jpeg_encode(s, image, quality)) throw std::runtime_error(std::string("JPEG encoding failed: ") + s.errors.message);
  return std::vector<std::uint8_t>(s.buffer, s.buffer + s.size);
}

void write_image(const fs::path& file, const cv::Mat& image, const ImageWriteOptions& options) {
  const std::string extension = lowercase(file.extension().string());
  std::vector<std::uint8_t> bytes;
  try {
    if (extension == ".png") {
      bytes = encode_png(image, options.png);
    } else if (extension == ".jpg" || extension == ".jpeg") {
      bytes = encode_jpeg(image, options.jpeg_quality);
    } else if ((extension == ".pgm" && image.channels() == 1) || (extension == ".ppm" && image.channels() == 3) ||
               extension == ".pnm") {
      bytes = encode_pnm(image);
    } else if (extension == ".pgm" || extension == ".ppm") {
      throw std::invalid_argument(extension + " holds " + (extension == ".pgm" ? "grey" : "3-channel colour") +
                                  " images, not " + describe_type(image));
    } else {
      throw std::invalid_argument("unknown image extension '" + extension + "' (use .png, .pgm, .ppm or .jpg)");
    }
  } catch (const std::exception& e) {
    throw InputError(file, std::string("cannot write image (") + e.what() + ")");
  }
  errno = 0;
  std::FILE* out = std::fopen(file.c_str(), "wb");
  if (out == nullptr) {
    const int error = errno;
    throw InputError(file, std::string("cannot write image (") + (error ? std::strerror(error) : "cannot create") + ")");
  }
  const std::size_t written = std::fwrite(bytes.data(), 1, bytes.size(), out);
  int error = written == bytes.size() ? 0 : (errno ? errno : EIO);
  // A full disk often shows only when the buffered tail is flushed.
  if (std::fclose(out) != 0 && error == 0) error = errno ? errno : EIO;
  if (error != 0) throw InputError(file, std::string("cannot write image (") + std::strerror(error) + ")");
}

}  // namespace nirslam
