#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <spdlog/spdlog.h>

#include "commands/subcommand.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/image/image_codec.hpp"
#include "nirslam/image/image_files.hpp"
#include "nirslam/photometric/exposure_sweep_calibration.hpp"
#include "nirslam/photometric/response_model.hpp"
#include "nirslam/session/session_format.hpp"

namespace nirslam::app {
namespace {

namespace fs = std::filesystem;

struct CalibrateSweepOptions {
  fs::path folder;
  fs::path times;
  fs::path out_dir;
  bool green = false;
  int max_valid_grey = 254;
  int min_valid_grey = 1;
  bool power_sweep = false;
  bool no_ambient = false;
  int viewpoint = 0;
};

// One image of an illuminator power sweep (sweep.csv of `nirslam simulate --sweep`, or a session).
// Power x exposure scales the lamp's irradiance; at 0 W the image holds the ambient light alone.
struct PowerSweepImage {
  fs::path file;
  double power_w = 0.0;
  double exposure = 0.0;  // exposure time x gain
};

// Reads the rows of `viewpoint` from sweep.csv (columns file, viewpoint, frame_index, timestamp_s,
// power_w, exposure_ms, gain, mean_grey). Rows at 0 W hold only the ambient light: the ambient
// term fits them, and ambient_share checks them.
std::vector<PowerSweepImage> read_power_sweep(const fs::path& folder, int viewpoint) {
  const fs::path csv = folder / "sweep.csv";
  std::ifstream in(csv);
  if (!in) throw InputError(csv, "cannot open (a power sweep folder holds sweep.csv, as `nirslam simulate --sweep` writes)");
  std::string line;
  if (!std::getline(in, line) || line.rfind("file,viewpoint,", 0) != 0)
    throw InputError(csv, 1, "expected the header 'file,viewpoint,frame_index,timestamp_s,power_w,exposure_ms,gain,mean_grey'");
  std::vector<PowerSweepImage> images;
  for (int number = 2; std::getline(in, line); ++number) {
    if (line.empty()) continue;
    std::vector<std::string> cells;
    std::stringstream row(line);
    for (std::string cell; std::getline(row, cell, ',');) cells.push_back(cell);
    if (cells.size() < 7) throw InputError(csv, number, "expected 8 comma-separated columns, got " + std::to_string(cells.size()));
    double values[4] = {};
    const char* names[4] = {"viewpoint", "power_w", "exposure_ms", "gain"};
    const int columns[4] = {1, 4, 5, 6};
    for (int k = 0; k < 4; ++k) {
      try {
        std::size_t used = 0;
        values[k] = std::stod(cells[static_cast<std::size_t>(columns[k])], &used);
        if (used != cells[static_cast<std::size_t>(columns[k])].size()) throw std::invalid_argument("trailing text");
      } catch (const std::exception&) {
        throw InputError(csv, number, std::string(names[k]) + " '" + cells[static_cast<std::size_t>(columns[k])] + "' is not a number");
      }
    }
    if (static_cast<int>(values[0]) != viewpoint) continue;
    if (!(values[1] >= 0.0) || !(values[2] > 0.0) || !(values[3] > 0.0))
      throw InputError(csv, number, "power must not be negative, exposure and gain must be positive");
    images.push_back({folder / cells[0], values[1], values[2] * values[3]});
  }
  if (std::count_if(images.begin(), images.end(), [](const PowerSweepImage& image) { return image.power_w > 0.0; }) < 2)
    throw InputError(csv, "fewer than 2 images with the lamp on at viewpoint " + std::to_string(viewpoint));
  return images;
}

// A recorded session (`nirslam record`, the GUI's Record tab) as a power sweep: the rig held still
// in front of a wall while the lamp is stepped through its powers. Every frame of the journal
// needs its reported exposure and lamp power. Of each run of frames at one power the first
// `kSettleFrames` are skipped (the lamp and the auto exposure settle after a change) and at most
// `kFramesPerPower` of the rest taken, evenly spread: frames at one power add only noise
// averaging, not another exposure. Frames at 0 W show the ambient light (see ambient_share).
std::vector<PowerSweepImage> read_power_sweep_session(const fs::path& folder) {
  constexpr std::size_t kSettleFrames = 2;
  constexpr std::size_t kFramesPerPower = 4;
  const fs::path journal = folder / session_files::kJournal;
  const JournalContents contents = read_journal(journal);
  std::vector<std::vector<const JournalEntry*>> runs;
  for (std::size_t i = 0; i < contents.entries.size(); ++i) {
    const JournalEntry& entry = contents.entries[i];
    const int line = static_cast<int>(i) + 2;  // after the header
    if (!entry.exposure_ms || !(*entry.exposure_ms > 0.0))
      throw InputError(journal, line, "exposure_ms: a power sweep needs every frame's reported exposure");
    if (!entry.illuminator_power_w || !(*entry.illuminator_power_w >= 0.0))
      throw InputError(journal, line, "illuminator_power_w: a power sweep needs every frame's lamp power");
    if (entry.gain && !(*entry.gain > 0.0)) throw InputError(journal, line, "gain: must be positive");
    if (runs.empty() || *runs.back().front()->illuminator_power_w != *entry.illuminator_power_w) runs.emplace_back();
    runs.back().push_back(&entry);
  }
  std::vector<PowerSweepImage> images;
  std::map<double, int> powers;
  for (const auto& run : runs) {
    const double power = *run.front()->illuminator_power_w;
    if (run.size() <= kSettleFrames) continue;
    const std::size_t settled = run.size() - kSettleFrames;
    const std::size_t taken = std::min(settled, kFramesPerPower);
    for (std::size_t k = 0; k < taken; ++k) {
      const JournalEntry& entry = *run[kSettleFrames + (k * settled) / taken];
      images.push_back({folder / entry.file, power, *entry.exposure_ms * entry.gain.value_or(1.0)});
    }
    if (power > 0.0) ++powers[power];
  }
  if (powers.size() < 2)
    throw InputError(journal, "a power sweep needs frames at 2 or more lamp powers above 0 W, each held for more than " +
                                  std::to_string(kSettleFrames) + " frames; this session has " +
                                  std::to_string(powers.size()));
  return images;
}

// How much of the light the sweep's weakest lamp image saw was ambient: per pixel the irradiance
// of a 0 W image over that of the lowest-power image, each G(I) / exposure under the fitted
// response, median over the pixels the lamp image shows unclipped and above black. Without the
// ambient term (--no-ambient) a share of a few percent already bends the response (the simulated
// street under its sky: 55 grey levels off, README "Illuminator correction"), so it warns then.
struct AmbientShare {
  double share = 0.0;
  int pixels = 0;
};
std::optional<AmbientShare> ambient_share(const cv::Mat& lamp_off, double lamp_off_exposure, const cv::Mat& weakest,
                                          double weakest_exposure, const ResponseModel& response, int max_valid_grey) {
  constexpr int kStep = 4;
  constexpr int kMinGrey = 10;  // where G is steep near black, the ratio says little
  if (lamp_off.size() != weakest.size()) return std::nullopt;
  const std::vector<double> G = response.inverse_table(256);
  std::vector<double> shares;
  for (int y = 0; y < weakest.rows; y += kStep)
    for (int x = 0; x < weakest.cols; x += kStep) {
      const int grey = weakest.at<std::uint8_t>(y, x);
      if (grey < kMinGrey || grey > max_valid_grey) continue;
      const double lamp = G[static_cast<std::size_t>(grey)] / weakest_exposure;
      shares.push_back(G[lamp_off.at<std::uint8_t>(y, x)] / lamp_off_exposure / lamp);
    }
  if (shares.empty()) return std::nullopt;
  std::nth_element(shares.begin(), shares.begin() + static_cast<std::ptrdiff_t>(shares.size() / 2), shares.end());
  return AmbientShare{shares[shares.size() / 2], static_cast<int>(shares.size())};
}

// The green channel of a colour file (a pixel whose red or blue channel clips has a grey value
// no response explains); grey files are used as they are.
cv::Mat read_green_or_grey(const fs::path& file) {
  const cv::Mat decoded = read_image(file);
  if (decoded.depth() != CV_8U) throw InputError(file, "--green needs 8-bit images");
  if (decoded.channels() == 1) return decoded;
  if (decoded.channels() < 3) throw InputError(file, "unsupported channel count");
  cv::Mat green;
  cv::extractChannel(decoded, green, 1);
  return green;
}

int run_calibrate_sweep(const CalibrateSweepOptions& options) {
  std::vector<fs::path> files;
  std::optional<std::vector<double>> times;
  // Power sweep: each image's power and exposure, the weakest lit image, the first lamp-off one.
  std::vector<PowerSweepFrame> sweep_frames;
  std::optional<std::size_t> weakest, lamp_off;
  if (options.power_sweep) {
    if (!options.times.empty()) throw InputError(options.times, "--times and --power-sweep exclude each other");
    const std::vector<PowerSweepImage> sweep = is_session_folder(options.folder)
                                                   ? read_power_sweep_session(options.folder)
                                                   : read_power_sweep(options.folder, options.viewpoint);
    for (const PowerSweepImage& image : sweep) {
      if (image.power_w == 0.0 && !lamp_off) lamp_off = files.size();
      if (image.power_w > 0.0 && (!weakest || image.power_w < sweep_frames[*weakest].power_w)) weakest = files.size();
      files.push_back(image.file);
      sweep_frames.push_back({image.power_w, image.exposure});
    }
  } else {
    files = list_image_files(options.folder);
  }
  if (files.empty()) throw InputError(options.folder, "no image files");

  if (!options.times.empty()) {
    std::map<std::string, double> by_name;
    for (const NamedExposureTime& t : read_exposure_times(options.times)) by_name[t.name] = t.seconds;
    times.emplace();
    for (const fs::path& file : files) {
      auto it = by_name.find(file.stem().string());
      if (it == by_name.end()) it = by_name.find(file.filename().string());
      if (it == by_name.end())
        throw InputError(options.times, "no exposure time for image '" + file.filename().string() + "'");
      times->push_back(it->second);
    }
  }

  int wide_images = 0;
  const auto load = [&](const fs::path& file) {
    cv::Mat image = options.green ? read_green_or_grey(file) : read_grey_image(file).image;
    if (image.depth() == CV_16U) {
      // The response model's grey scale is 0..255 whatever the bit depth (a 16-bit value g sits
      // at g / 257, as the pipeline and pcalib.txt take it); NIR cameras record Y10-Y16.
      cv::Mat scaled;
      image.convertTo(scaled, CV_8U, 1.0 / 257.0);
      image = scaled;
      ++wide_images;
    }
    return image;
  };
  std::vector<cv::Mat> images;
  for (const fs::path& file : files) images.push_back(load(file));

  ExposureSweepOptions sweep_options;
  sweep_options.max_valid_grey = options.max_valid_grey;
  sweep_options.min_valid_grey = options.min_valid_grey;
  const ExposureSweepResult result = options.power_sweep
                                         ? calibrate_power_sweep(images, sweep_frames, !options.no_ambient, sweep_options)
                                         : calibrate_exposure_sweep(images, times, sweep_options);

  const std::string resolution =
      !options.power_sweep ? to_string(result.resolution)
      : options.no_ambient ? "illuminator power sweep (radiance proportional to the lamp's power x exposure x gain; "
                             "ambient light assumed negligible)"
                           : "illuminator power sweep (radiance proportional to the lamp's power x exposure x gain, "
                             "plus per point an ambient radiance proportional to exposure x gain)";
  std::printf("Response calibration from %s: %zu images in %s\n",
              options.power_sweep ? "an illuminator power sweep" : "an exposure sweep", files.size(),
              options.folder.string().c_str());
  if (wide_images > 0) std::printf("  %d 16-bit images read on the 0..255 scale (grey / 257)\n", wide_images);
  std::printf("  ambiguity resolution: %s\n", resolution.c_str());
  if (!times && !options.power_sweep)
    std::printf("  warning: without exposure times the gamma is pinned only by the response basis; the ratios\n"
                "           below are self-consistent but not reliable as exposure ratios (pass --times)\n");
  // "brightness": the factor on the given exposure that the image's own grey values fit best
  // (ExposureSweepImage::brightness_exposure_factor); only with given exposures.
  const bool exposures_given = times.has_value() || options.power_sweep;
  std::printf("  %-24s %6s %10s %12s %9s %8s %10s  %s\n", "image", "used", "unclipped", "exposure", "ratio", "rms[gl]",
              exposures_given ? "brightness" : "", "note");
  for (std::size_t j = 0; j < files.size(); ++j) {
    const ExposureSweepImage& info = result.images[j];
    const std::string brightness =
        exposures_given && info.used && result.ok ? fmt::format("{:.3f}x", info.brightness_exposure_factor) : "";
    std::printf("  %-24s %6s %10d %12.6g %9.5g %8.2f %10s  %s\n", files[j].filename().string().c_str(),
                info.used ? "yes" : "no", info.unclipped_samples, info.exposure, info.ratio, info.residual_rms_grey,
                brightness.c_str(), info.note.c_str());
  }
  const Eigen::Vector4d& c = result.response.coefficients();
  std::printf("  points %d, observations %d, residual %.3f grey levels, %d iterations, monotonic %s\n",
              result.point_count, result.observation_count, result.residual_rms_grey, result.iterations,
              result.monotonic ? "yes" : "no");
  std::printf("  c = %.6f %.6f %.6f %.6f\n", c[0], c[1], c[2], c[3]);
  std::printf("  observed grey range: 1 %% of the samples at %.0f or above\n", result.highest_grey);
  if (const std::string advice = sweep_range_advice(result); !advice.empty())
    std::printf("  warning: %s\n", advice.c_str());
  if (result.ok && !result.reported_exposure_check.empty()) {
    std::string named;
    for (std::size_t j = 0; j < files.size(); ++j)
      if (result.images[j].brightness_disagrees)
        named += fmt::format("{}{} ({:.2f}x)", named.empty() ? "" : ", ", files[j].filename().string(),
                             result.images[j].brightness_exposure_factor);
    std::printf("  warning: the brightness of %s disagrees with the given exposure%s by that factor (over %.0f %% and\n"
                "           over the sweep's own scatter): a camera that reports its exposure control's value rather\n"
                "           than the frame's own (read back late, or applied frames later) does this, and it bends the\n"
                "           response; leave such images out or give their true exposures\n",
                named.c_str(), options.power_sweep ? " x power" : "", 100.0 * (kReportedExposureTolerance - 1.0));
  }
  std::optional<AmbientShare> ambient;
  if (lamp_off && weakest && result.ok)
    ambient = ambient_share(images[*lamp_off], sweep_frames[*lamp_off].exposure, images[*weakest],
                            sweep_frames[*weakest].exposure, result.response, options.max_valid_grey);
  if (ambient) {
    constexpr double kMaxAmbientShare = 0.02;
    std::printf("  ambient light (%s at 0 W): %.1f %% of the irradiance at %g W (median of %d pixels)\n",
                files[*lamp_off].filename().string().c_str(), 100.0 * ambient->share, sweep_frames[*weakest].power_w,
                ambient->pixels);
    if (options.no_ambient && ambient->share > kMaxAmbientShare)
      std::printf("  warning: the lamp is not the only light, so the response is biased (--no-ambient drops the\n"
                  "           ambient term): sweep without --no-ambient, or with the lamp alone and other lights off\n");
  }
  if (result.ambient_modelled && result.ok && result.weakest_image >= 0)
    std::printf("  ambient term: median %.1f %% of the lamp's irradiance at %g W over the points\n",
                100.0 * result.ambient_share_at_weakest,
                sweep_frames[static_cast<std::size_t>(result.weakest_image)].power_w);
  if (!result.ok) {
    spdlog::error("calibration failed: {}", result.reason);
    return 1;
  }

  if (!options.out_dir.empty()) {
    fs::create_directories(options.out_dir);
    write_pcalib(options.out_dir / "pcalib.txt", result.response.inverse_table());
    nlohmann::json images_json = nlohmann::json::array();
    for (std::size_t j = 0; j < files.size(); ++j) {
      const ExposureSweepImage& info = result.images[j];
      images_json.push_back({{"file", files[j].filename().string()},
                             {"used", info.used},
                             {"exposure", info.exposure},
                             {"ratio", info.ratio},
                             {"unclipped_samples", info.unclipped_samples},
                             {"residual_rms_grey", info.residual_rms_grey},
                             {"brightness_exposure_factor", exposures_given && info.used
                                                                ? nlohmann::json(info.brightness_exposure_factor)
                                                                : nlohmann::json()},
                             {"note", info.note}});
    }
    const nlohmann::json summary = {
        {"response_coefficients", {c[0], c[1], c[2], c[3]}},
        {"monotonic", result.monotonic},
        {"ambiguity_resolution", resolution},
        {"exposure_times_given", times.has_value() && !options.power_sweep},
        {"power_sweep", options.power_sweep},
        {"ambient_share_at_lowest_power", ambient ? nlohmann::json(ambient->share) : nlohmann::json(nullptr)},
        {"ambient_modelled", result.ambient_modelled},
        {"ambient_share_fitted",
         result.ambient_modelled ? nlohmann::json(result.ambient_share_at_weakest) : nlohmann::json(nullptr)},
        {"reference_image", files[static_cast<std::size_t>(result.reference_image)].filename().string()},
        {"residual_rms_grey", result.residual_rms_grey},
        {"highest_grey", result.highest_grey},
        {"reported_exposure_check", result.reported_exposure_check.empty()
                                        ? nlohmann::json(nullptr)
                                        : nlohmann::json(result.reported_exposure_check)},
        {"points", result.point_count},
        {"observations", result.observation_count},
        {"images", images_json}};
    const fs::path json_file = options.out_dir / "sweep_calibration.json";
    std::ofstream out(json_file);
    out << summary.dump(2) << "\n";
    if (!out) throw std::runtime_error(json_file.string() + ": cannot write");
    std::printf("  wrote %s and %s\n", (options.out_dir / "pcalib.txt").string().c_str(), json_file.string().c_str());
  }
  return 0;
}

}  // namespace

void add_calibrate_sweep_command(CLI::App& parent, CommandAction& action) {
  auto options = std::make_shared<CalibrateSweepOptions>();
  CLI::App* cmd = parent.add_subcommand(
      "calibrate-sweep",
      "Calibrate the camera response from a static exposure sweep (tripod, static scene, images with different\n"
      "exposures): the 4-coefficient response of the photometric model, the exposure ratios, the residual.\n"
      "With --times the recorded exposure times resolve the gamma/scale ambiguity; without, the exposures are\n"
      "estimated too (reference image = 1) and the ratios are not reliable. With --power-sweep, a static\n"
      "illuminator power sweep instead (the lamp's radiance proportional to power, plus per point an ambient radiance\n"
      "that follows the exposure only): a simulated sweep's folder, or a recorded session in which the rig stood still\n"
      "while the lamp was stepped through its powers. Writes DSO's pcalib.txt and sweep_calibration.json with --out.");
  cmd->add_option("sweep_dir", options->folder, "Folder of the sweep's images")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--times", options->times,
                  "Exposure times, lines 'NAME: SECONDS' (NAME = image file name without extension; SECONDS a number "
                  "or a fraction like 1/250)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--out", options->out_dir, "Folder for pcalib.txt and sweep_calibration.json");
  cmd->add_flag("--power-sweep", options->power_sweep,
                "sweep_dir is an illuminator power sweep (sweep.csv + images/, as `nirslam simulate --sweep` writes, or a "
                "recorded session whose frames report their exposure and lamp power): "
                "power x exposure x gain are the lamp's known exposures; light from elsewhere is fitted per point (see "
                "--no-ambient)");
  cmd->add_flag("--no-ambient", options->no_ambient,
                "Power sweep: no ambient term (the lamp the only light; lamp-off images are then only checked)");
  cmd->add_option("--viewpoint", options->viewpoint, "Power sweep: which viewpoint's images to use")->capture_default_str();
  cmd->add_flag("--green", options->green, "Use the green channel of colour images instead of the grey conversion");
  cmd->add_option("--min-valid", options->min_valid_grey, "Smallest grey value counted as unclipped (default 1)")
      ->check(CLI::Range(1, 254));
  cmd->add_option("--max-valid", options->max_valid_grey, "Largest grey value counted as unclipped (default 254)")
      ->check(CLI::Range(2, 255));
  cmd->callback([options, &action] { action = [options] { return run_calibrate_sweep(*options); }; });
}

}  // namespace nirslam::app
