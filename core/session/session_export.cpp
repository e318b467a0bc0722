#include "nirslam/session/session_export.hpp"

#include <zip.h>

#include <algorithm>
#include <fstream>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "nirslam/common/error.hpp"
#include "nirslam/eval/evaluation.hpp"
#include "nirslam/eval/trajectory.hpp"
#include "nirslam/eval/trajectory_plot.hpp"
#include "nirslam/image/image_codec.hpp"
#include "nirslam/photometric/response_model.hpp"
#include "nirslam/session/odometry_output.hpp"
#include "nirslam/session/session_format.hpp"
#include "nirslam/session/session_plots.hpp"
#include "nirslam/sources/tum_monovo_reader.hpp"

namespace nirslam {
namespace fs = std::filesystem;
namespace {

std::string html_escape(const std::string& text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '&': out += "&amp;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

void write_text(const fs::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
  out.flush();
  if (!out) throw std::runtime_error(file.string() + ": cannot write (disk full?)");
}

void copy_session_file(const fs::path& from, const fs::path& to) {
  std::error_code error;
  fs::copy_file(from, to, fs::copy_options::overwrite_existing, error);
  if (error) throw std::runtime_error(to.string() + ": cannot copy from " + from.string() + " (" + error.message() + ")");
}

std::string optional_text(const std::optional<double>& value, const char* format = "{:.6f}") {
  return value ? fmt::format(fmt::runtime(format), *value) : std::string();
}

// Every regular file under `folder` into `archive`, with paths relative to the folder's parent
// so the archive unpacks into one folder. PNG members are stored: they are compressed already.
void write_zip(const fs::path& folder, const fs::path& archive) {
  int error_code = 0;
  zip_t* zip = zip_open(archive.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &error_code);
  if (!zip) {
    zip_error_t error;
    zip_error_init_with_code(&error, error_code);
    const std::string message = zip_error_strerror(&error);
    zip_error_fini(&error);
    throw std::runtime_error(archive.string() + ": cannot create the archive (" + message + ")");
  }
  std::vector<fs::path> files;
  for (const auto& item : fs::recursive_directory_iterator(folder))
    if (item.is_regular_file()) files.push_back(item.path());
  std::sort(files.begin(), files.end());
  const std::string root = folder.filename().string();
  for (const fs::path& file : files) {
    const std::string name = root + "/" + fs::relative(file, folder).generic_string();
    zip_source_t* source = zip_source_file(zip, file.c_str(), 0, -1);
    const zip_int64_t index = source ? zip_file_add(zip, name.c_str(), source, ZIP_FL_ENC_UTF_8) : -1;
    if (index < 0) {
      if (source) zip_source_free(source);
      const std::string message = zip_strerror(zip);
      zip_discard(zip);
      throw std::runtime_error(archive.string() + ": cannot add " + name + " (" + message + ")");
    }
    if (file.extension() == ".png") zip_set_file_compression(zip, static_cast<zip_uint64_t>(index), ZIP_CM_STORE, 0);
  }
  if (zip_close(zip) != 0) {
    const std::string message = zip_strerror(zip);
    zip_discard(zip);
    throw std::runtime_error(archive.string() + ": cannot write the archive (" + message + ")");
  }
}

struct ReportContext {
  const SessionMetadata* metadata = nullptr;
  const std::vector<JournalEntry>* journal = nullptr;
  ExportSummary* summary = nullptr;
  std::vector<std::pair<std::string, std::string>> figures;  // file, caption
  double mean_entropy = 0.0;
  std::size_t poses = 0;
};

std::string render_report_html(const ReportContext& c) {
  const SessionMetadata& m = *c.metadata;
  const std::vector<JournalEntry>& journal = *c.journal;
  const double duration = journal.size() > 1 ? journal.back().timestamp_s - journal.front().timestamp_s : 0.0;
  std::string rows;
  const auto row = [&](const std::string& key, const std::string& value) {
    rows += fmt::format("<tr><th>{}</th><td>{}</td></tr>\n", html_escape(key), html_escape(value));
  };
  row("Source", m.source_kind + ": " + m.source_description);
  row("Recorded", m.started_utc + (m.stopped_utc.empty() ? "" : " to " + m.stopped_utc));
  row("State", std::string(to_string(m.state)) + (m.stop_reason.empty() ? "" : " (" + m.stop_reason + ")"));
  row("Frames", fmt::format("{} ({}x{}, {}-bit, {:.1f} s)", journal.size(), m.width, m.height, m.bit_depth, duration));
  row("Dropped frames", fmt::format("{}", m.frames_dropped));
  row("Camera", m.camera.empty() ? "no calibration" : m.camera);
  row("Mean entropy", fmt::format("{:.3f} bit", c.mean_entropy));
  if (c.poses > 0) row("Trajectory", fmt::format("{} poses", c.poses));
  if (!c.summary->evaluation.empty()) row("Accuracy", c.summary->evaluation);
  row("Software", "nirslam " + m.nirslam_version);
  if (!m.notes.empty()) row("Operator notes", m.notes);
  if (!m.recovery_report.empty()) row("Recovery", m.recovery_report);

  std::string figures;
  for (const auto& [file, caption] : c.figures)
    figures += fmt::format("<figure><img src=\"{}\" alt=\"{}\"><figcaption>{}</figcaption></figure>\n", file,
                           html_escape(caption), html_escape(caption));
  std::string files;
  for (const std::string& f : c.summary->files) files += fmt::format("<li><a href=\"{0}\">{0}</a></li>", html_escape(f));
  std::string notes;
  for (const std::string& n : c.summary->notes) notes += "<li>" + html_escape(n) + "</li>";
  return fmt::format(R"(<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>nirslam session report</title>
<style>
body {{ font-family: sans-serif; background: #eef1f5; color: #222; margin: 24px; }}
h1 {{ font-size: 22px; margin: 0 0 12px 0; }}
table {{ border-collapse: collapse; background: #fff; margin-bottom: 16px; }}
th, td {{ text-align: left; padding: 4px 12px; border-bottom: 1px solid #dde; font-size: 14px; }}
figure {{ margin: 0 0 16px 0; background: #fff; padding: 8px; display: inline-block; }}
figure img {{ max-width: 100%; display: block; }}
figcaption {{ font-size: 13px; color: #555; padding-top: 4px; }}
ul {{ font-size: 13px; }}
</style></head><body>
<h1>nirslam session report</h1>
<table>
{}</table>
{}
<h2>Files</h2><ul>{}</ul>
{}
</body></html>
)",
                     rows, figures, files, notes.empty() ? "" : "<h2>Not included</h2><ul>" + notes + "</ul>");
}

}  // namespace

ExportSummary export_session(const fs::path& session, const fs::path& out_argument, const ExportOptions& options) {
  // "DIR/" and "DIR" are the same folder (and the archive DIR.zip, not DIR/.zip).
  const fs::path out = out_argument.has_filename() ? out_argument : out_argument.parent_path();
  const SessionMetadata metadata = read_session_metadata(session);
  if (metadata.state == SessionState::Recording)
    throw InputError(session / session_files::kMetadata, "state",
                     "the session is still 'recording' (being recorded, or interrupted): run `nirslam recover " +
                         session.string() + "` first");
  const std::vector<JournalEntry> journal = read_journal(session / session_files::kJournal).entries;
  if (journal.empty()) throw InputError(session / session_files::kJournal, "the session has no frames to export");
  std::error_code error;
  if (fs::exists(out, error) && !fs::is_empty(out, error))
    throw InputError(out, "the output folder exists and is not empty: choose a new folder");
  fs::create_directories(out / "images", error);
  if (error) throw std::runtime_error(out.string() + ": cannot create the output folder (" + error.message() + ")");

  ExportSummary summary;
  summary.folder = out;
  summary.frames = static_cast<std::int64_t>(journal.size());

  // Frames and times.txt.
  std::string times = "# id timestamp_s exposure_ms (nirslam export of " + session.string() + ")\n";
  for (std::size_t i = 0; i < journal.size(); ++i) {
    const JournalEntry& e = journal[i];
    const std::string id = fmt::format("{:05d}", i);
    const fs::path from = session / e.file;
    const fs::path to = out / "images" / (id + ".png");
    if (fs::path(e.file).extension() == ".png") {
      copy_session_file(from, to);
    } else {
      write_image(to, read_image(from), ImageWriteOptions{.png = {.compression_level = 1}});
    }
    times += e.exposure_ms ? fmt::format("{} {:.9f} {:.6f}\n", id, e.timestamp_s, *e.exposure_ms)
                           : fmt::format("{} {:.9f}\n", id, e.timestamp_s);
  }
  summary.files.push_back("images/");
  write_text(out / "times.txt", times);
  summary.files.push_back("times.txt");

  if (fs::exists(session / session_files::kCamera)) {
    copy_session_file(session / session_files::kCamera, out / "camera.txt");
    summary.files.push_back("camera.txt");
  } else {
    summary.notes.push_back("camera.txt: the source had no geometric calibration");
  }

  // Photometric calibration.
  const fs::path calibration = session / session_files::kCalibration;
  std::vector<double> inverse_response;
  cv::Mat vignette;
  if (fs::exists(calibration / "pcalib.txt")) {
    copy_session_file(calibration / "pcalib.txt", out / "pcalib.txt");
    summary.files.push_back("pcalib.txt");
    inverse_response = read_pcalib(out / "pcalib.txt");
    if (fs::exists(calibration / "vignette.png")) {
      copy_session_file(calibration / "vignette.png", out / "vignette.png");
      summary.files.push_back("vignette.png");
      vignette = read_vignette_png(out / "vignette.png");
    }
    fs::copy(calibration, out / "calibration", fs::copy_options::recursive, error);
    if (error) throw std::runtime_error((out / "calibration").string() + ": cannot copy (" + error.message() + ")");
    summary.files.push_back("calibration/");
  } else {
    summary.notes.push_back("pcalib.txt, vignette.png: the session holds no photometric calibration");
  }

  // Odometry outputs.
  for (const char* name : {session_files::kTrajectory, session_files::kKeyframes, session_files::kPoints}) {
    if (!fs::exists(session / name)) continue;
    copy_session_file(session / name, out / name);
    summary.files.push_back(name);
  }
  std::vector<Trajectory> segments;
  if (fs::exists(out / session_files::kTrajectory)) {
    segments = read_trajectory_segments(out / session_files::kTrajectory);
    segments.erase(std::remove_if(segments.begin(), segments.end(), [](const Trajectory& t) { return t.empty(); }),
                   segments.end());
  } else {
    summary.notes.push_back("trajectory.txt, keyframes.txt, points.ply: no odometry ran while recording");
  }

  Trajectory ground_truth;
  for (const JournalEntry& e : journal)
    if (e.T_world_cam_truth) ground_truth.poses.push_back({e.timestamp_s, *e.T_world_cam_truth});
  if (!ground_truth.empty()) {
    write_tum(out / "groundtruth.txt", ground_truth);
    summary.files.push_back("groundtruth.txt");
  }

  // Per-frame table.
  std::string frames_csv = "id,source_index,timestamp_s,exposure_ms,gain,illuminator_power_w,entropy_bits,tracked\n";
  double entropy_sum = 0.0;
  int entropy_count = 0;
  for (std::size_t i = 0; i < journal.size(); ++i) {
    const JournalEntry& e = journal[i];
    frames_csv += fmt::format("{:05d},{},{:.9f},{},{},{},{},{}\n", i, e.source_index, e.timestamp_s, optional_text(e.exposure_ms),
                              optional_text(e.gain), optional_text(e.illuminator_power_w),
                              optional_text(e.entropy_bits), e.T_world_cam ? 1 : 0);
    if (e.entropy_bits) {
      entropy_sum += *e.entropy_bits;
      ++entropy_count;
    }
  }
  write_text(out / "frames.csv", frames_csv);
  summary.files.push_back("frames.csv");
  if (fs::exists(session / session_files::kMetrics)) {
    copy_session_file(session / session_files::kMetrics, out / "metrics.csv");
    summary.files.push_back("metrics.csv");
  }

  // Plots and the report.
  fs::create_directories(out / "report");
  ReportContext report;
  report.metadata = &metadata;
  report.journal = &journal;
  report.summary = &summary;
  report.mean_entropy = entropy_count > 0 ? entropy_sum / entropy_count : 0.0;
  const auto add_plot = [&](const std::string& name, const std::string& caption, const auto& render) {
    try {
      const cv::Mat image = render();
      write_png(out / "report" / name, image);
      summary.plots.push_back("report/" + name);
      report.figures.emplace_back("report/" + name, caption);
    } catch (const std::invalid_argument& e) {
      summary.notes.push_back(name + ": " + e.what());
    }
  };
  add_plot("entropy.png", "Image entropy (bits) of every recorded frame", [&] { return render_entropy_plot(journal); });
  std::vector<std::pair<double, double>> estimated_exposures;
  if (fs::exists(calibration / "times.txt")) {
    try {
      for (const TimesEntry& t : read_times_file(calibration / "times.txt"))
        if (t.exposure_ms) estimated_exposures.emplace_back(t.timestamp_s, *t.exposure_ms);
    } catch (const InputError& e) {
      summary.notes.push_back(std::string("estimated exposures: ") + e.what());
    }
  }
  add_plot("exposure.png", "Exposure over time: reported by the camera, and as the calibration estimated it",
           [&] { return render_exposure_plot(journal, estimated_exposures); });
  if (!inverse_response.empty())
    add_plot("photometric.png", "Photometric calibration: inverse response and vignette",
             [&] { return render_photometric_plot(inverse_response, vignette); });
  std::optional<EvaluationResult> evaluation;
  if (!segments.empty() && ground_truth.size() >= 3) {
    const auto longest = std::max_element(segments.begin(), segments.end(),
                                          [](const Trajectory& a, const Trajectory& b) { return a.size() < b.size(); });
    try {
      evaluation = evaluate(*longest, ground_truth);
      summary.evaluation = evaluation_headline(*evaluation);
    } catch (const std::exception& e) {
      summary.notes.push_back(std::string("accuracy against ground truth: ") + e.what());
    }
  }
  for (const Trajectory& t : segments) report.poses += t.size();
  if (!segments.empty()) {
    add_plot("trajectory.png", evaluation ? "Trajectory, top view: the estimate aligned to the ground truth"
                                          : "Trajectory, top view (odometry frame)",
             [&] {
               if (evaluation)
                 return render_trajectory_top_view({evaluation->estimate_positions_aligned}, ground_truth.positions());
               std::vector<std::vector<Eigen::Vector3d>> paths;
               for (const Trajectory& t : segments) paths.push_back(t.positions());
               return render_trajectory_top_view(paths, {});
             });
  }
  if (evaluation)
    add_plot("error_heatmap.png", "Trajectory error against ground truth (ATE per pose)",
             [&] {
               ErrorPlotOptions plot;
               plot.width = 1000;
               plot.height = 760;
               return render_evaluation_heat_map(ground_truth.positions(), *evaluation, plot);
             });
  summary.files.push_back("report/");
  summary.files.push_back("report.html");
  write_text(out / "report.html", render_report_html(report));

  if (options.archive) {
    const fs::path archive = fs::path(out.string() + ".zip");
    write_zip(out, archive);
    summary.archive = archive;
  }
  return summary;
}

}  // namespace nirslam
