#include "nirslam/sim/sequence_writer.hpp"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <span>
#include <tuple>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <spdlog/fmt/fmt.h>

#include "nirslam/image/image_codec.hpp"

namespace nirslam {

namespace fs = std::filesystem;

namespace {

[[noreturn]] void write_failed(const fs::path& file, const char* what, int error) {
  throw std::runtime_error(fmt::format("{}: {} ({})", file.string(), what, error ? std::strerror(error) : "stream error"));
}

// A text file written line by line; every write is checked.
class TextFile {
public:
  explicit TextFile(fs::path path) : path_(std::move(path)) {
    errno = 0;
    out_.open(path_, std::ios::out | std::ios::trunc);
    if (!out_) write_failed(path_, "cannot create", errno);
  }
  void write(const std::string& text) {
    errno = 0;
    out_ << text << std::flush;
    if (!out_) write_failed(path_, "cannot write", errno);
  }
  void close() {
    errno = 0;
    out_.close();
    if (!out_) write_failed(path_, "cannot write", errno);
  }

private:
  fs::path path_;
  std::ofstream out_;
};

void create_folder(const fs::path& folder) {
  std::error_code error;
  fs::create_directories(folder, error);
  if (error) throw std::runtime_error(folder.string() + ": cannot create folder (" + error.message() + ")");
}

std::string image_name(std::int64_t i) { return fmt::format("{:05d}.png", i); }

std::optional<ResponsePreset> preset_of(const ResponseModel& response) {
  for (ResponsePreset p : {ResponsePreset::Linear, ResponsePreset::Gamma, ResponsePreset::Log, ResponsePreset::Filmic})
    if ((ResponseModel::from_preset(p).coefficients() - response.coefficients()).cwiseAbs().maxCoeff() < 1e-12) return p;
  return std::nullopt;
}

nlohmann::json ground_truth_json(const Simulator& sim, const std::string& mode) {
  const SimulatorOptions& o = sim.options();
  const CameraModel& cam = *sim.camera();
  const sim::Lighting light = sim.lighting(o.powers_w.front());
  const auto preset = preset_of(o.response);
  nlohmann::json j;
  j["generator"] = "nirslam simulate";
  j["nirslam_version"] = NIRSLAM_VERSION;
  j["mode"] = mode;
  j["scene"] = {{"kind", sim::to_string(o.scene)},
                {"seed", o.seed},
                {"primitives", sim.scene().primitives.size()},
                {"sky_radiance_w_m2_sr", sim.scene().sky_radiance},
                {"ambient_irradiance_w_m2", light.ambient_irradiance},
                {"glossy_floor", sim.scene().glossy_floor
                                     ? nlohmann::json{{"z_m", sim.scene().glossy_floor->z},
                                                      {"r0", sim.scene().glossy_floor->r0},
                                                      {"strength", sim.scene().glossy_floor->strength},
                                                      {"model", "Lambertian + mirror image weighted by strength * Schlick Fresnel"}}
                                     : nlohmann::json(nullptr)}};
  const sim::Trajectory& traj = sim.trajectory();
  j["trajectory"] = {{"motion", sim::to_string(o.motion)},
                     {"loop_length_m", traj.loop_length()},
                     {"loop_period_s", traj.period()},
                     {"speed_mps", traj.speed()},
                     {"pose_convention", "T_world_cam; camera x right, y down, z forward; world z up; metres"},
                     {"timestamp_is", "the middle of the exposure"}};
  nlohmann::json camera = {{"model", cam.name()},
                           {"width", cam.width()},
                           {"height", cam.height()},
                           {"fx", cam.fx()},
                           {"fy", cam.fy()},
                           {"cx", cam.cx()},
                           {"cy", cam.cy()},
                           {"pixel_centre_convention", "pixel (col, row) centred at (col, row)"},
                           {"supersampling", o.supersampling},
                           {"fps", o.fps},
                           {"motion_blur", o.motion_blur}};
  if (cam.type() == CameraModelType::Fov) camera["omega"] = cam.distortion()[0];
  camera["capture_rule"] = o.capture_rule ? nlohmann::json{{"max_interval_s", o.capture_rule->max_interval_s},
                                                          {"max_distance_m", o.capture_rule->max_distance_m}}
                                          : nlohmann::json(nullptr);
  j["camera"] = camera;
  j["illuminator"] = {
      {"wavelength_nm", 850},
      {"powers_w", o.powers_w},
      {"power_step_frames", o.power_step_frames},
      {"efficiency", o.light_efficiency},
      {"offset_cam_m", {o.light_offset_cam.x(), o.light_offset_cam.y(), o.light_offset_cam.z()}},
      {"beam", {{"pattern", "B(alpha) = cos(alpha)^m about the optical axis"},
                {"half_angle_deg", o.beam_half_angle_deg},
                {"exponent_m", light.illuminator.beam_exponent()}}},
      {"axial_intensity_w_per_sr_per_w", light.illuminator.axial_intensity() / std::max(light.illuminator.power_w, 1e-12)},
      {"irradiance_model", "E = J0 B(alpha) cos(theta) / d^2 + E_ambient (1 + n_z) / 2, J0 = efficiency P (m + 1) / (2 pi)"}};
  j["response"] = {{"basis", "sqrt-Legendre: f(X) = u + u(1-u) sum_k c_k P_{k-1}(2u-1), u = sqrt(X) (response_model.hpp)"},
                   {"coefficients", {o.response.coefficients()[0], o.response.coefficients()[1],
                                     o.response.coefficients()[2], o.response.coefficients()[3]}},
                   {"preset", preset ? nlohmann::json(to_string(*preset)) : nlohmann::json(nullptr)},
                   {"inverse_response_grey", o.response.inverse_table(256)}};
  j["vignette"] = {{"model", "V(r) = 1 + v1 r^2 + v2 r^4 + v3 r^6, r = distance to the image centre / half-diagonal"},
                   {"coefficients", {o.vignette.v[0], o.vignette.v[1], o.vignette.v[2]}}};
  j["sensor"] = {{"bit_depth", o.bit_depth},
                 {"sensitivity_per_w_m2_sr_s", o.sensitivity},
                 {"full_well_e", o.full_well_e},
                 {"read_noise_e", o.read_noise_e},
                 {"noise", o.noise},
                 {"model", "I = round(f(clamp(g n' / FW, 0, 1)) (2^bits - 1)), n = min(k e V L, 1) FW, n' = n + sqrt(n + read^2) N(0,1)"}};
  j["exposure"] = {{"mode", o.exposure_mode == ExposureMode::Auto ? "auto" : "fixed"},
                   {"initial_ms", o.exposure_ms},
                   {"min_ms", o.min_exposure_ms},
                   {"max_ms", std::min(o.max_exposure_ms, 1000.0 / o.fps)},
                   {"target_grey", o.target_grey},
                   {"damping", o.ae_damping},
                   {"max_gain", o.max_gain}};
  j["files"] = {{"images", "images/%05d.png"},
                {"times", "times.txt: id timestamp_s exposure_ms"},
                {"camera", "camera.txt (DSO)"},
                {"pcalib", "pcalib.txt: G(0..255) in grey levels"},
                {"vignette", "vignette.png: V scaled to its maximum, 16-bit"},
                {"groundtruth", "groundtruth.txt: TUM, T_world_cam"},
                {"frames", "frames.csv: per-frame exposure, gain, illuminator power"}};
  return j;
}

// The common files of a sequence folder.
void write_calibration(const Simulator& sim, const fs::path& folder) {
  write_dso_camera_file(folder / "camera.txt", *sim.camera());
  write_pcalib(folder / "pcalib.txt", sim.options().response.inverse_table(256));
  write_vignette_png(folder / "vignette.png", sim.vignette_map());
}

std::string tum_line(double t, const SE3& pose) {
  const Eigen::Vector3d& p = pose.translation();
  const Eigen::Quaterniond& q = pose.unit_quaternion();
  return fmt::format("{:.9f} {:.9f} {:.9f} {:.9f} {:.9f} {:.9f} {:.9f} {:.9f}\n", t, p.x(), p.y(), p.z(), q.x(), q.y(), q.z(), q.w());
}

cv::Mat depth_png(const cv::Mat& depth) {
  cv::Mat mm;
  depth.convertTo(mm, CV_16UC1, 1000.0);  // saturates at 65.535 m
  return mm;
}

std::string label_of(const Frame& f) {
  return fmt::format("#{}  {:.1f} s  {:.2f} ms  {:.0f} W", f.index, f.timestamp_s, f.exposure_ms.value_or(0.0),
                     f.illuminator_power_w.value_or(0.0));
}

void write_sheet(const SimulationOutput& output, const std::vector<cv::Mat>& frames, const std::vector<std::string>& labels) {
  if (!output.contact_sheet || frames.empty()) return;
  if (output.contact_sheet->has_parent_path()) create_folder(output.contact_sheet->parent_path());
  write_image(*output.contact_sheet,
              make_contact_sheet(frames, labels, output.contact_sheet_columns, output.contact_sheet_tile_width),
              ImageWriteOptions{.png = {.compression_level = 9}});
}

// The folders and text files both writers produce: images/ (and depth/), the calibration files,
// times.txt, groundtruth.txt and one per-image table, with their headers.
struct SequenceFiles {
  SequenceFiles(const Simulator& sim, const fs::path& folder, const SimulationOutput& output,
                const std::string& table_name, const std::string& table_header)
      // The folders must exist before the first file opens: prepare() runs first.
      : times((prepare(sim, folder, output), folder / "times.txt")),
        truth(folder / "groundtruth.txt"),
        table(folder / table_name) {
    truth.write("# timestamp tx ty tz qx qy qz qw  (T_world_cam: camera to world, metres)\n");
    table.write(table_header);
  }
  static void prepare(const Simulator& sim, const fs::path& folder, const SimulationOutput& output) {
    create_folder(folder / "images");
    if (output.write_depth) create_folder(folder / "depth");
    write_calibration(sim, folder);
  }

  TextFile times;
  TextFile truth;
  TextFile table;
};

}  // namespace

void write_dso_camera_file(const fs::path& file, const CameraModel& camera) {
  std::string first, third;
  if (camera.type() == CameraModelType::Pinhole) {
    first = fmt::format("Pinhole {:.9g} {:.9g} {:.9g} {:.9g} 0", camera.fx(), camera.fy(), camera.cx(), camera.cy());
    third = "none";
  } else if (camera.type() == CameraModelType::Fov) {
    first = fmt::format("FOV {:.9g} {:.9g} {:.9g} {:.9g} {:.9g}", camera.fx(), camera.fy(), camera.cx(), camera.cy(),
                        camera.distortion()[0]);
    third = "crop";
  } else {
    throw std::invalid_argument("write_dso_camera_file: only pinhole and FOV cameras are written");
  }
  TextFile out(file);
  out.write(fmt::format("{}\n{} {}\n{}\n{} {}\n", first, camera.width(), camera.height(), third, camera.width(),
                        camera.height()));
  out.close();
}

cv::Mat make_contact_sheet(const std::vector<cv::Mat>& frames, const std::vector<std::string>& labels, int columns,
                           int tile_width) {
  if (frames.empty() || columns < 1 || tile_width < 16) throw std::invalid_argument("contact sheet: nothing to show");
  const int gap = 4;
  const int tile_height = static_cast<int>(std::lround(static_cast<double>(tile_width) * frames[0].rows / frames[0].cols));
  const int cols = std::min<int>(columns, static_cast<int>(frames.size()));
  const int rows = static_cast<int>((frames.size() + static_cast<std::size_t>(cols) - 1) / static_cast<std::size_t>(cols));
  cv::Mat sheet(rows * tile_height + (rows + 1) * gap, cols * tile_width + (cols + 1) * gap, CV_8UC1, cv::Scalar(24));
  for (std::size_t i = 0; i < frames.size(); ++i) {
    cv::Mat eight;
    if (frames[i].depth() == CV_16U)
      frames[i].convertTo(eight, CV_8UC1, 1.0 / 257.0);
    else
      eight = frames[i];
    cv::Mat tile;
    cv::resize(eight, tile, cv::Size(tile_width, tile_height), 0, 0, cv::INTER_AREA);
    const int r = static_cast<int>(i) / cols, c = static_cast<int>(i) % cols;
    const cv::Rect where(gap + c * (tile_width + gap), gap + r * (tile_height + gap), tile_width, tile_height);
    tile.copyTo(sheet(where));
    if (i < labels.size()) {
      const cv::Point at(where.x + 6, where.y + tile_height - 8);
      cv::putText(sheet, labels[i], at + cv::Point(1, 1), cv::FONT_HERSHEY_SIMPLEX, 0.42, cv::Scalar(0), 1, cv::LINE_AA);
      cv::putText(sheet, labels[i], at, cv::FONT_HERSHEY_SIMPLEX, 0.42, cv::Scalar(235), 1, cv::LINE_AA);
    }
  }
  return sheet;
}

SequenceSummary write_simulated_sequence(const SimulatorOptions& options, const fs::path& folder,
                                         const SimulationOutput& output, const SimulationProgress& progress) {
  if (options.frames <= 0) throw std::invalid_argument("simulate: the number of frames must be positive");
  Simulator sim(options);
  SequenceFiles files(sim, folder, output, "frames.csv",
                      "index,file,timestamp_s,exposure_ms,gain,illuminator_power_w,mean_grey\n");
  TextFile& times = files.times;
  TextFile& truth = files.truth;
  TextFile& frames_csv = files.table;

  const std::int64_t n = options.frames;
  const int sheet_count = std::max(1, std::min<int>(output.contact_sheet_frames, static_cast<int>(n)));
  std::vector<cv::Mat> sheet;
  std::vector<std::string> labels;
  SequenceSummary summary;
  summary.folder = folder;
  summary.min_exposure_ms = std::numeric_limits<double>::infinity();
  double grey_sum = 0.0;
  const auto started = std::chrono::steady_clock::now();
  int next_sheet = 0;
  while (std::optional<SimulatedFrame> f = sim.next(output.write_depth)) {
    const Frame& frame = f->frame;
    const std::string name = image_name(frame.index);
    write_image(folder / "images" / name, frame.image);
    if (output.write_depth) write_image(folder / "depth" / name, depth_png(f->depth));
    times.write(fmt::format("{:05d} {:.9f} {:.6f}\n", frame.index, frame.timestamp_s, *frame.exposure_ms));
    truth.write(tum_line(frame.timestamp_s, f->T_world_cam));
    frames_csv.write(fmt::format("{},images/{},{:.9f},{:.6f},{:.6f},{:.6f},{:.6f}\n", frame.index, name, frame.timestamp_s,
                                 *frame.exposure_ms, *frame.gain, *frame.illuminator_power_w, f->mean_grey));
    // Contact sheet frames spread evenly over the sequence.
    if (next_sheet < sheet_count &&
        frame.index == (sheet_count == 1 ? 0 : static_cast<std::int64_t>(next_sheet) * (n - 1) / (sheet_count - 1))) {
      sheet.push_back(frame.image.clone());
      labels.push_back(label_of(frame));
      ++next_sheet;
    }
    summary.images = frame.index + 1;
    summary.duration_s = frame.timestamp_s;
    summary.min_exposure_ms = std::min(summary.min_exposure_ms, *frame.exposure_ms);
    summary.max_exposure_ms = std::max(summary.max_exposure_ms, *frame.exposure_ms);
    grey_sum += f->mean_grey;
    if (progress) progress(summary.images, n);
  }
  times.close();
  truth.close();
  frames_csv.close();
  summary.mean_grey = grey_sum / static_cast<double>(std::max<std::int64_t>(summary.images, 1));
  summary.render_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();

  nlohmann::json j = ground_truth_json(sim, "sequence");
  j["frames"] = summary.images;
  j["exposure_range_ms"] = {summary.min_exposure_ms, summary.max_exposure_ms};
  TextFile json(folder / "groundtruth.json");
  json.write(j.dump(2) + "\n");
  json.close();
  write_sheet(output, sheet, labels);
  return summary;
}

SequenceSummary write_power_sweep(const SimulatorOptions& options, const PowerSweepOptions& sweep, const fs::path& folder,
                                  const SimulationOutput& output, const SimulationProgress& progress) {
  if (sweep.powers_w.empty()) throw std::invalid_argument("power sweep: no powers given");
  if (sweep.viewpoints < 1 || sweep.stride < 1) throw std::invalid_argument("power sweep: viewpoints and stride must be positive");
  for (const double p : sweep.powers_w)
    if (!(p >= 0.0)) throw std::invalid_argument("power sweep: powers must not be negative");
  SimulatorOptions o = options;
  o.frames = 0;
  Simulator sim(o);
  SequenceFiles files(sim, folder, output, "sweep.csv",
                      "file,viewpoint,frame_index,timestamp_s,power_w,exposure_ms,gain,mean_grey\n");
  TextFile& times = files.times;
  TextFile& truth = files.truth;
  TextFile& csv = files.table;

  const std::int64_t total = sweep.viewpoints * static_cast<std::int64_t>(sweep.powers_w.size());
  SequenceSummary summary;
  summary.folder = folder;
  summary.min_exposure_ms = std::numeric_limits<double>::infinity();
  std::vector<cv::Mat> sheet;
  std::vector<std::string> labels;
  double grey_sum = 0.0;
  const auto started = std::chrono::steady_clock::now();
  std::int64_t image = 0;
  cv::Mat radiance, depth;
  for (std::int64_t v = 0; v < sweep.viewpoints; ++v) {
    const std::int64_t frame_index = v * sweep.stride;
    const double t = sim.frame_time(frame_index);
    const SE3 pose = sim.trajectory().pose(t);
    truth.write(tum_line(t, pose));
    for (std::size_t k = 0; k < sweep.powers_w.size(); ++k) {
      const double power = sweep.powers_w[k];
      double exposure = o.exposure_ms, gain = 1.0, mean = 0.0;
      // The viewpoint does not move: render once (motion blur off: the camera is held still).
      const sim::Lighting light = sim.lighting(power);
      sim.renderer().render(std::span<const SE3>(&pose, 1), light, radiance, output.write_depth ? &depth : nullptr);
      const std::uint64_t key = 0x5EEDull << 40 | static_cast<std::uint64_t>(image) << 8;
      Frame frame;
      if (o.exposure_mode == ExposureMode::Auto) {
        for (int s = 0; s < sweep.settle_frames; ++s) {
          sim.expose(radiance, exposure, gain, key + static_cast<std::uint64_t>(s) + 1, &mean);
          std::tie(exposure, gain) = sim.auto_exposure_step(exposure, gain, mean);
        }
      }
      frame = sim.expose(radiance, exposure, gain, key, &mean);
      frame.index = image;
      frame.timestamp_s = t;
      frame.illuminator_power_w = power;
      const std::string name = image_name(image);
      write_image(folder / "images" / name, frame.image);
      if (output.write_depth) write_image(folder / "depth" / name, depth_png(depth));
      times.write(fmt::format("{:05d} {:.9f} {:.6f}\n", image, t, exposure));
      csv.write(fmt::format("images/{},{},{},{:.9f},{:.6f},{:.6f},{:.6f},{:.6f}\n", name, v, frame_index, t, power, exposure,
                            gain, mean));
      if (v == 0 && static_cast<int>(sheet.size()) < output.contact_sheet_frames) {
        sheet.push_back(frame.image.clone());
        labels.push_back(label_of(frame));
      }
      summary.min_exposure_ms = std::min(summary.min_exposure_ms, exposure);
      summary.max_exposure_ms = std::max(summary.max_exposure_ms, exposure);
      grey_sum += mean;
      ++image;
      summary.images = image;
      if (progress) progress(image, total);
    }
    summary.duration_s = t;
  }
  times.close();
  truth.close();
  csv.close();
  summary.mean_grey = grey_sum / static_cast<double>(std::max<std::int64_t>(image, 1));
  summary.render_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  nlohmann::json j = ground_truth_json(sim, "power_sweep");
  j["sweep"] = {{"powers_w", sweep.powers_w},
                {"viewpoints", sweep.viewpoints},
                {"stride_frames", sweep.stride},
                {"settle_frames", sweep.settle_frames},
                {"images", image}};
  TextFile json(folder / "groundtruth.json");
  json.write(j.dump(2) + "\n");
  json.close();
  write_sheet(output, sheet, labels);
  return summary;
}

}  // namespace nirslam
