#include "nirslam/photometric/calibration_output.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <unordered_map>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "nirslam/common/error.hpp"
#include "nirslam/common/median.hpp"
#include "nirslam/photometric/exposure_scale.hpp"
#include "nirslam/photometric/grey_range_advice.hpp"

namespace nirslam {

namespace fs = std::filesystem;

namespace {

[[noreturn]] void write_failed(const fs::path& file) {
  throw std::runtime_error(file.string() + ": cannot write (" + (errno ? std::strerror(errno) : "stream error") + ")");
}

nlohmann::json json_number_or_null(const std::optional<double>& value) {
  return value && std::isfinite(*value) ? nlohmann::json(*value) : nlohmann::json(nullptr);
}

}  // namespace

std::optional<PhotometricGroundTruth> read_simulated_ground_truth(const fs::path& folder) {
  const fs::path json_file = folder / "groundtruth.json";
  if (!fs::exists(json_file)) return std::nullopt;
  PhotometricGroundTruth truth;
  try {
    std::ifstream in(json_file);
    const nlohmann::json j = nlohmann::json::parse(in);
    const auto& c = j.at("response").at("coefficients");
    truth.response = ResponseModel(Eigen::Vector4d(c.at(0).get<double>(), c.at(1).get<double>(), c.at(2).get<double>(),
                                                   c.at(3).get<double>()));
    const auto& v = j.at("vignette").at("coefficients");
    truth.vignette.v = Eigen::Vector3d(v.at(0).get<double>(), v.at(1).get<double>(), v.at(2).get<double>());
  } catch (const nlohmann::json::exception& e) {
    throw InputError(json_file, std::string("not a simulator ground truth file (") + e.what() + ")");
  }
  const fs::path csv = folder / "frames.csv";
  std::ifstream in(csv);
  if (!in) throw InputError(csv, "file is missing (needed with groundtruth.json for the true exposures)");
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (number == 1 || line.empty()) continue;  // header
    // index,file,timestamp_s,exposure_ms,gain,illuminator_power_w,mean_grey
    std::vector<std::string> fields;
    std::stringstream stream(line);
    for (std::string field; std::getline(stream, field, ',');) fields.push_back(field);
    try {
      if (fields.size() < 5) throw std::invalid_argument("too few fields");
      truth.exposures.emplace_back(std::stoll(fields[0]), std::stod(fields[3]) * std::stod(fields[4]));
    } catch (const std::exception&) {
      throw InputError(csv, number, "expected 'index,file,timestamp_s,exposure_ms,gain,...'");
    }
  }
  return truth;
}

PhotometricErrors compare_with_ground_truth(const ResponseModel& response, const VignetteModel& vignette,
                                            const std::vector<ExposureSample>& exposures,
                                            const PhotometricGroundTruth& truth, int width, int height) {
  PhotometricErrors errors;
  const std::vector<double> g_est = response.inverse_table(256);
  const std::vector<double> g_true = truth.response.inverse_table(256);
  for (std::size_t i = 0; i < 256; ++i) {
    const double d = std::abs(g_est[i] - g_true[i]);
    errors.response_mean_grey += d / 256.0;
    errors.response_max_grey = std::max(errors.response_max_grey, d);
  }
  // Vignette over the image (every 4th pixel), each scaled to its maximum as vignette.png is.
  {
    double max_est = 0.0, max_true = 0.0;
    std::vector<std::pair<double, double>> values;
    for (int y = 0; y < height; y += 4)
      for (int x = 0; x < width; x += 4) {
        const double r = VignetteModel::radius(x, y, width, height);
        values.emplace_back(vignette(r), truth.vignette(r));
        max_est = std::max(max_est, values.back().first);
        max_true = std::max(max_true, values.back().second);
      }
    for (const auto& [est, tru] : values) {
      const double d = std::abs(est / max_est - tru / max_true);
      errors.vignette_mean += d / static_cast<double>(values.size());
      errors.vignette_max = std::max(errors.vignette_max, d);
    }
  }
  std::unordered_map<std::int64_t, double> true_exposure(truth.exposures.begin(), truth.exposures.end());
  // On the reported scale when the source reported exposures (as times.txt has them), else
  // normalised to the truth at the first estimated frame (the Normalisation ambiguity).
  const ReportedExposureScale reported = reported_exposure_scale(exposures);
  std::optional<double> scale;
  if (reported.frames > 0) scale = reported.factor;
  std::vector<double> relative;
  std::vector<std::pair<double, double>> pairs;  // (estimated, true)
  for (const ExposureSample& s : exposures) {
    const auto it = true_exposure.find(s.frame_index);
    if (!s.estimated || it == true_exposure.end() || !(*s.estimated > 0.0)) continue;
    if (!scale) scale = it->second / *s.estimated;
    const double e = *s.estimated * *scale;
    const double d = std::abs(e - it->second);
    errors.exposure_mean_ms += d;
    errors.exposure_max_ms = std::max(errors.exposure_max_ms, d);
    relative.push_back(std::abs(e / it->second - 1.0));
    errors.exposure_max_relative = std::max(errors.exposure_max_relative, relative.back());
    pairs.emplace_back(*s.estimated, it->second);
  }
  errors.exposure_frames = static_cast<int>(relative.size());
  if (!relative.empty()) {
    errors.exposure_mean_ms /= static_cast<double>(relative.size());
    errors.exposure_median_relative = median_in_place(relative);
    std::vector<double> log_ratio;
    for (const auto& [est, tru] : pairs) log_ratio.push_back(std::log(tru / est));
    const double aligned_scale = std::exp(median_in_place(log_ratio));
    relative.clear();
    for (const auto& [est, tru] : pairs) relative.push_back(std::abs(est * aligned_scale / tru - 1.0));
    errors.exposure_median_relative_aligned = median_in_place(relative);
  }
  return errors;
}

void write_calibration_output(const fs::path& folder, const PhotometricEstimate& estimate,
                              const std::vector<ExposureSample>& exposures, const CalibrationOutputInfo& info,
                              const std::optional<PhotometricErrors>& errors) {
  std::error_code error;
  fs::create_directories(folder, error);
  if (error) throw std::runtime_error(folder.string() + ": cannot create output folder (" + error.message() + ")");
  write_pcalib(folder / "pcalib.txt", estimate.response.inverse_table(256));
  write_vignette_png(folder / "vignette.png", estimate.vignette.render(info.width, info.height));

  const ReportedExposureScale scale = reported_exposure_scale(exposures);
  const fs::path times = folder / "times.txt";
  {
    errno = 0;
    std::ofstream out(times);
    if (!out) write_failed(times);
    char line[96];
    for (const ExposureSample& s : exposures) {
      if (!s.estimated) continue;
      std::snprintf(line, sizeof line, "%05lld %.9f %.6f\n", static_cast<long long>(s.frame_index), s.timestamp_s,
                    *s.estimated * scale.factor);
      out << line;
    }
    out.close();
    if (!out) write_failed(times);
  }

  const Eigen::Vector4d& c = estimate.response.coefficients();
  const std::optional<GreyRangeAdvice> range_advice = online_grey_range_advice(estimate);
  nlohmann::json frames = nlohmann::json::array();
  for (const ExposureSample& s : exposures)
    frames.push_back({{"index", s.frame_index},
                      {"timestamp_s", s.timestamp_s},
                      {"exposure_estimated", s.estimated ? nlohmann::json(*s.estimated * scale.factor) : nlohmann::json(nullptr)},
                      {"exposure_reported", json_number_or_null(s.reported)},
                      {"status", static_cast<int>(s.status)}});
  nlohmann::json keyframes = nlohmann::json::array();
  for (const auto& [index, exposure] : estimate.keyframe_exposures) keyframes.push_back({{"index", index}, {"exposure", exposure}});
  nlohmann::json j = {
      {"source", info.source},
      {"image_size", {info.width, info.height}},
      {"frames", info.frames},
      {"response",
       {{"basis", "sqrt-Legendre: f(X) = u + u(1-u) sum_k c_k P_{k-1}(2u-1), u = sqrt(X) (response_model.hpp)"},
        {"coefficients", {c[0], c[1], c[2], c[3]}},
        {"monotonic", estimate.response.is_monotonic()},
        {"inverse_response_grey", estimate.response.inverse_table(256)}}},
      {"vignette",
       {{"model", "V(r) = 1 + v1 r^2 + v2 r^4 + v3 r^6, r = distance to the image centre / half-diagonal"},
        {"coefficients", {estimate.vignette.v[0], estimate.vignette.v[1], estimate.vignette.v[2]}}}},
      {"observed",
       {{"grey_range", estimate.grey_high > estimate.grey_low ? nlohmann::json{estimate.grey_low, estimate.grey_high}
                                                              : nlohmann::json(nullptr)},
        {"vignette_max_radius", estimate.radius_high > 0.0 ? nlohmann::json(estimate.radius_high) : nlohmann::json(nullptr)},
        // Below grey kOnlineAdvisedHighestGrey: how much brighter the images would have to be to measure
        // the top of the response (grey_range_advice.hpp); null when the samples reach it or nothing was fitted.
        {"exposure_factor_to_reach_top", range_advice ? nlohmann::json(range_advice->exposure_factor) : nlohmann::json(nullptr)},
        {"advice", range_advice ? nlohmann::json(describe(*range_advice)) : nlohmann::json(nullptr)},
        {"note", "1st-99th percentile of the back end's samples: outside the grey range the inverse response is the "
                 "straightest continuation of log G over log I, beyond the radius V is the model's continuation "
                 "(straight over r^2 with vignette_rim_curvature_weight); neither is measured there; null: no "
                 "back-end estimate (the initial or a given model)"}}},
      {"lamp_beam_exponent", estimate.beam_exponent ? nlohmann::json(*estimate.beam_exponent) : nlohmann::json(nullptr)},
      // The lens vignette the beam multiplies (V_lens(r) cos(alpha)^m, what the odometry's lamp
      // factor applies; "vignette" above is the sextic closest to it).
      {"lamp_beam_lens", estimate.beam_lens ? nlohmann::json(std::vector<double>(estimate.beam_lens->v.data(), estimate.beam_lens->v.data() + 3))
                                            : nlohmann::json(nullptr)},
      {"ambiguity_resolution", std::string(to_string(estimate.ambiguity))},
      {"ambiguity_detail", estimate.ambiguity_detail},
      {"exposure_unit", estimate.ambiguity == AmbiguityResolution::Normalisation ? "relative (first frame = 1)"
                                                                                 : "ms x gain"},
      {"convergence",
       {{"converged", estimate.converged},
        {"iterations", estimate.iterations},
        {"cost_per_observation", estimate.cost},
        {"residual_rms_grey", estimate.residual_rms},
        {"keyframes", estimate.keyframes},
        {"points", estimate.points},
        {"keyframes_dropped", estimate.keyframes_dropped},
        {"model_version", estimate.model_version},
        {"status", estimate.status}}},
      {"timing", {{"wall_time_s", info.wall_time_s}, {"mean_front_end_ms", info.mean_front_end_ms}}},
      {"exposure_scale",
       {{"factor", scale.factor},
        {"frames", scale.frames},
        {"note", "the estimated exposures (times.txt, exposures) are the front end's chain of ratios times this "
                 "factor, the median of reported / estimated over the frames that report an exposure (1 and 0 "
                 "frames: none reported, the chain's first frame = 1)"}}},
      {"keyframe_exposures", keyframes},
      {"exposures", frames},
      {"errors", nullptr}};
  if (errors)
    j["errors"] = {{"response_mean_grey", errors->response_mean_grey},
                   {"response_max_grey", errors->response_max_grey},
                   {"vignette_mean", errors->vignette_mean},
                   {"vignette_max", errors->vignette_max},
                   {"exposure_mean_ms", errors->exposure_mean_ms},
                   {"exposure_max_ms", errors->exposure_max_ms},
                   {"exposure_median_relative", errors->exposure_median_relative},
                   {"exposure_frames", errors->exposure_frames},
                   {"exposure_max_relative", errors->exposure_max_relative},
                   {"exposure_median_relative_aligned", errors->exposure_median_relative_aligned},
                   {"exposure_normalisation", scale.frames > 0 ? "as written (on the reported scale)"
                                                               : "estimate scaled to the truth at the first estimated frame"}};
  const fs::path json_file = folder / "calibration.json";
  errno = 0;
  std::ofstream out(json_file);
  if (!out) write_failed(json_file);
  out << j.dump(2) << '\n';
  out.close();
  if (!out) write_failed(json_file);
}

}  // namespace nirslam
