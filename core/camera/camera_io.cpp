#include "nirslam/camera/camera_io.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "nirslam/common/error.hpp"
#include "nirslam/common/text_fields.hpp"

namespace nirslam {

namespace {

struct NumberedLine {
  int number = 0;  // 1-based, as an editor shows it
  std::vector<std::string> tokens;
};

std::vector<double> numbers_of(const NumberedLine& line, std::size_t first,
                               const std::filesystem::path& file) {
  std::vector<double> values;
  for (std::size_t i = first; i < line.tokens.size(); ++i) {
    const std::optional<double> value = parse_double(line.tokens[i]);
    if (!value) throw InputError(file, line.number, "'" + line.tokens[i] + "' is not a number");
    values.push_back(*value);
  }
  return values;
}

// "width height", both positive.
std::pair<int, int> parse_size_line(const NumberedLine& line, const std::filesystem::path& file,
                                    const std::string& what) {
  const auto width = line.tokens.size() == 2 ? parse_integer<int>(line.tokens[0]) : std::nullopt;
  const auto height = line.tokens.size() == 2 ? parse_integer<int>(line.tokens[1]) : std::nullopt;
  if (!width || !height)
    throw InputError(file, line.number, "expected the " + what + " as two integers 'width height'");
  if (*width <= 0 || *height <= 0)
    throw InputError(file, line.number, "the " + what + " must be positive, got " +
                                            std::to_string(*width) + " " + std::to_string(*height));
  return {*width, *height};
}

// Line 1 without the image size: which model and its raw (possibly relative) parameters.
struct ModelLine {
  CameraModelType type = CameraModelType::Pinhole;
  Eigen::Vector4d intrinsics = Eigen::Vector4d::Zero();
  std::vector<double> distortion;
};

ModelLine parse_model_line(const NumberedLine& line, const std::filesystem::path& file) {
  const std::string& first = line.tokens.front();
  ModelLine model;
  std::vector<double> values;
  if (parse_double(first)) {
    // DSO's keyword-less forms, kept for backwards compatibility.
    values = numbers_of(line, 0, file);
    if (values.size() == 5)
      model.type = values[4] == 0.0 ? CameraModelType::Pinhole : CameraModelType::Fov;
    else if (values.size() == 8)
      model.type = CameraModelType::RadTan;
    else
      throw InputError(file, line.number,
                       "expected 5 numbers (fx fy cx cy omega), 8 numbers (fx fy cx cy k1 k2 p1 "
                       "p2) or a model keyword, got " + std::to_string(values.size()) + " numbers");
  } else {
    const std::string keyword = lowercase(first);
    values = numbers_of(line, 1, file);
    std::size_t expected = 8;
    if (keyword == "pinhole") {
      model.type = CameraModelType::Pinhole;
      expected = values.size() == 4 ? 4 : 5;
    } else if (keyword == "fov") {
      model.type = CameraModelType::Fov;
      expected = 5;
    } else if (keyword == "radtan") {
      model.type = CameraModelType::RadTan;
    } else if (keyword == "equidistant" || keyword == "kannalabrandt") {
      model.type = CameraModelType::Equidistant;
    } else {
      throw InputError(file, line.number,
                       "unknown camera model '" + first +
                           "' (expected Pinhole, FOV, RadTan, EquiDistant or KannalaBrandt)");
    }
    if (values.size() != expected)
      throw InputError(file, line.number,
                       first + " takes " + std::to_string(expected) + " numbers, got " +
                           std::to_string(values.size()));
    if (model.type == CameraModelType::Pinhole && values.size() == 5 && values[4] != 0.0)
      throw InputError(file, line.number,
                       "Pinhole has no distortion: the fifth number must be 0 (use FOV for the "
                       "ATAN model)");
  }
  model.intrinsics = Eigen::Vector4d(values[0], values[1], values[2], values[3]);
  model.distortion.assign(values.begin() + 4, values.end());
  return model;
}

std::shared_ptr<const CameraModel> make_model(const ModelLine& model, int width, int height) {
  const auto& d = model.distortion;
  switch (model.type) {
    case CameraModelType::Pinhole:
      return std::make_shared<PinholeCamera>(width, height, model.intrinsics);
    case CameraModelType::RadTan:
      return std::make_shared<RadTanCamera>(width, height, model.intrinsics,
                                            Eigen::Vector4d(d[0], d[1], d[2], d[3]));
    case CameraModelType::Fov:
      return std::make_shared<FovCamera>(width, height, model.intrinsics, d[0]);
    case CameraModelType::Equidistant:
      return std::make_shared<EquidistantCamera>(width, height, model.intrinsics,
                                                 Eigen::Vector4d(d[0], d[1], d[2], d[3]));
  }
  throw std::invalid_argument("unknown camera model type");
}

}  // namespace

DsoCameraCalibration parse_dso_camera(std::istream& in, const std::filesystem::path& file) {
  std::vector<NumberedLine> lines;
  int number = 0;
  for (std::string text; std::getline(in, text);) {
    ++number;
    const auto fields = split_blanks(text);
    NumberedLine line{number, std::vector<std::string>(fields.begin(), fields.end())};
    if (line.tokens.empty() || line.tokens.front().front() == '#') continue;
    lines.push_back(std::move(line));
  }
  static constexpr const char* kExpected[] = {
      "the camera model (e.g. 'RadTan fx fy cx cy k1 k2 p1 p2')", "the input size 'width height'",
      "the rectification (crop, full, none or 'fx fy cx cy 0')", "the output size 'width height'"};
  if (lines.size() < 4)
    throw InputError(file, number + 1,
                     "file ends early: expected " + std::string(kExpected[lines.size()]));
  if (lines.size() > 4)
    throw InputError(file, lines[4].number,
                     "unexpected content after the four lines of a camera file");

  // Lines 1 and 2: the input camera.
  const ModelLine model = parse_model_line(lines[0], file);
  const auto [input_width, input_height] = parse_size_line(lines[1], file, "input image size");
  Eigen::Vector4d intrinsics = model.intrinsics;
  // DSO's rule: principal point coordinates below 1 can only be fractions of the image size.
  if (intrinsics[2] < 1.0 && intrinsics[3] < 1.0)
    intrinsics = absolute_from_relative_intrinsics(intrinsics, input_width, input_height);
  DsoCameraCalibration calibration;
  try {
    ModelLine absolute = model;
    absolute.intrinsics = intrinsics;
    calibration.input = make_model(absolute, input_width, input_height);
  } catch (const std::invalid_argument& error) {
    throw InputError(file, lines[0].number, error.what());
  }

  // Lines 3 and 4: the output pinhole.
  const NumberedLine& rectification = lines[2];
  const auto [output_width, output_height] = parse_size_line(lines[3], file, "output image size");
  RectificationSpec& output = calibration.output;
  output.width = output_width;
  output.height = output_height;
  const std::string mode = lowercase(rectification.tokens.front());
  if (rectification.tokens.size() == 1 && mode == "crop") {
    output.mode = RectificationMode::Crop;
  } else if (rectification.tokens.size() == 1 && mode == "full") {
    output.mode = RectificationMode::Full;
  } else if (rectification.tokens.size() == 1 && mode == "none") {
    output.mode = RectificationMode::SameK;
    if (output_width != input_width || output_height != input_height)
      throw InputError(file, lines[3].number,
                       "rectification 'none' needs the output size to equal the input size " +
                           std::to_string(input_width) + " " + std::to_string(input_height));
  } else {
    if (!parse_double(rectification.tokens.front()))
      throw InputError(file, rectification.number,
                       "expected crop, full, none or relative output intrinsics 'fx fy cx cy 0', "
                       "got '" + rectification.tokens.front() + "'");
    const std::vector<double> values = numbers_of(rectification, 0, file);
    if (values.size() != 4 && values.size() != 5)
      throw InputError(file, rectification.number,
                       "output intrinsics take 4 or 5 numbers 'fx fy cx cy 0', got " +
                           std::to_string(values.size()));
    if (values.size() == 5 && values[4] != 0.0)
      throw InputError(file, rectification.number,
                       "the output camera is a pinhole: the fifth number must be 0");
    if (values[2] > 1.0 || values[3] > 1.0)
      throw InputError(file, rectification.number,
                       "output intrinsics must be relative to the output size (cx, cy <= 1)");
    if (!(values[0] > 0.0 && values[1] > 0.0))
      throw InputError(file, rectification.number, "output focal lengths must be positive");
    output.mode = RectificationMode::Explicit;
    output.intrinsics = absolute_from_relative_intrinsics(
        Eigen::Vector4d(values[0], values[1], values[2], values[3]), output_width, output_height);
  }
  return calibration;
}

DsoCameraCalibration read_dso_camera_file(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw InputError(file, "cannot open camera file");
  return parse_dso_camera(in, file);
}

// ---------------------------------------------------------------------------------------------
// EuRoC sensor.yaml

namespace {

std::string where(const YAML::Node& node) {
  const YAML::Mark mark = node.Mark();
  return mark.line >= 0 ? " (line " + std::to_string(mark.line + 1) + ")" : std::string();
}

YAML::Node required(const YAML::Node& root, const std::filesystem::path& file,
                          const std::string& field) {
  const YAML::Node node = root[field];
  if (!node || node.IsNull()) throw InputError(file, field, "missing");
  return node;
}

std::string scalar_string(const YAML::Node& node, const std::filesystem::path& file,
                          const std::string& field) {
  if (!node.IsScalar()) throw InputError(file, field, "expected a single value" + where(node));
  return node.Scalar();
}

double scalar_double(const YAML::Node& node, const std::filesystem::path& file,
                     const std::string& field) {
  const std::optional<double> value = parse_double(scalar_string(node, file, field));
  if (!value) throw InputError(file, field, "'" + node.Scalar() + "' is not a number" + where(node));
  return *value;
}

std::vector<double> number_list(const YAML::Node& node, const std::filesystem::path& file,
                                const std::string& field, std::size_t expected) {
  if (!node.IsSequence() || node.size() != expected)
    throw InputError(file, field,
                     "expected a list of " + std::to_string(expected) + " numbers" + where(node));
  std::vector<double> values;
  for (std::size_t i = 0; i < expected; ++i)
    values.push_back(scalar_double(node[i], file, field + "[" + std::to_string(i) + "]"));
  return values;
}

Eigen::Matrix4d parse_transform(const YAML::Node& node, const std::filesystem::path& file,
                                const std::string& field) {
  // EuRoC writes {cols: 4, rows: 4, data: [16 numbers, row-major]}; accept a bare list as well.
  YAML::Node data = node;
  if (node.IsMap()) {
    const auto member = [&](const char* key) {
      const YAML::Node value = node[key];
      if (!value || value.IsNull()) throw InputError(file, field + "." + key, "missing");
      return value;
    };
    for (const char* dimension : {"rows", "cols"}) {
      const YAML::Node size = member(dimension);
      if (scalar_double(size, file, field + "." + dimension) != 4.0)
        throw InputError(file, field + "." + dimension, "expected 4" + where(size));
    }
    data = member("data");
  }
  const std::vector<double> values = number_list(data, file, field + ".data", 16);
  Eigen::Matrix4d T;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) T(r, c) = values[static_cast<std::size_t>(4 * r + c)];
  if (!T.row(3).isApprox(Eigen::RowVector4d(0.0, 0.0, 0.0, 1.0), 1e-9))
    throw InputError(file, field, "last row must be 0 0 0 1" + where(data));
  return T;
}

InputError yaml_error(const std::filesystem::path& file, const YAML::Exception& error,
                      const std::string& prefix) {
  if (error.mark.line >= 0) return InputError(file, error.mark.line + 1, prefix + error.msg);
  return InputError(file, prefix + error.msg);
}

}  // namespace

EurocCameraSensor read_euroc_sensor_yaml(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw InputError(file, "cannot open sensor file");
  std::ostringstream content;
  content << in.rdbuf();
  std::string text = content.str();
  // OpenCV's FileStorage writes "%YAML:1.0", which is not a valid YAML directive. Blank it out
  // (keeping the newline, so yaml-cpp's line numbers still match the file).
  if (text.rfind("%YAML:", 0) == 0) text.erase(0, text.find('\n'));

  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::ParserException& error) {
    throw yaml_error(file, error, "YAML syntax error: ");
  }
  if (!root.IsMap()) throw InputError(file, "expected a YAML mapping of sensor fields");

  EurocCameraSensor sensor;
  try {
    const YAML::Node model_node = required(root, file, "camera_model");
    const std::string model = lowercase(scalar_string(model_node, file, "camera_model"));
    if (model != "pinhole")
      throw InputError(file, "camera_model",
                       "unsupported camera model '" + model_node.Scalar() +
                           "' (only pinhole, with radial-tangential or equidistant distortion)" +
                           where(model_node));

    const YAML::Node intrinsics_node = required(root, file, "intrinsics");
    const std::vector<double> k = number_list(intrinsics_node, file, "intrinsics", 4);
    const YAML::Node resolution_node = required(root, file, "resolution");
    const std::vector<double> resolution = number_list(resolution_node, file, "resolution", 2);
    for (const double size : resolution)
      if (!(size >= 1.0 && size <= 1e6 && std::floor(size) == size))
        throw InputError(file, "resolution",
                         "expected two positive integers [width, height]" + where(resolution_node));
    const int width = static_cast<int>(resolution[0]);
    const int height = static_cast<int>(resolution[1]);
    const Eigen::Vector4d fu_fv_cu_cv(k[0], k[1], k[2], k[3]);

    const YAML::Node distortion_node = required(root, file, "distortion_model");
    const std::string distortion = lowercase(scalar_string(distortion_node, file, "distortion_model"));
    try {
      if (distortion == "radial-tangential" || distortion == "radtan") {
        const std::vector<double> d = number_list(required(root, file, "distortion_coefficients"),
                                                  file, "distortion_coefficients", 4);
        sensor.camera = std::make_shared<RadTanCamera>(width, height, fu_fv_cu_cv,
                                                       Eigen::Vector4d(d[0], d[1], d[2], d[3]));
      } else if (distortion == "equidistant") {
        const std::vector<double> d = number_list(required(root, file, "distortion_coefficients"),
                                                  file, "distortion_coefficients", 4);
        sensor.camera = std::make_shared<EquidistantCamera>(
            width, height, fu_fv_cu_cv, Eigen::Vector4d(d[0], d[1], d[2], d[3]));
      } else if (distortion == "none") {
        sensor.camera = std::make_shared<PinholeCamera>(width, height, fu_fv_cu_cv);
      } else {
        throw InputError(file, "distortion_model",
                         "unsupported distortion model '" + distortion_node.Scalar() +
                             "' (expected radial-tangential, equidistant or none)" +
                             where(distortion_node));
      }
    } catch (const std::invalid_argument& error) {
      throw InputError(file, "intrinsics", error.what() + where(intrinsics_node));
    }

    if (const YAML::Node T = root["T_BS"]; T && !T.IsNull())
      sensor.T_body_sensor = parse_transform(T, file, "T_BS");
    if (const YAML::Node rate = root["rate_hz"]; rate && !rate.IsNull()) {
      sensor.rate_hz = scalar_double(rate, file, "rate_hz");
      if (!(*sensor.rate_hz > 0.0)) throw InputError(file, "rate_hz", "must be positive" + where(rate));
    }
    if (const YAML::Node comment = root["comment"]; comment && comment.IsScalar())
      sensor.comment = comment.Scalar();
  } catch (const YAML::Exception& error) {
    // Structural surprises (a map where a list belongs, ...) that the checks above did not catch.
    throw yaml_error(file, error, "");
  }
  return sensor;
}

}  // namespace nirslam
