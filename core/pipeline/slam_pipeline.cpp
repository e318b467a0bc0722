#include "nirslam/pipeline/slam_pipeline.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "nirslam/common/elapsed.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/photometric/given_calibration.hpp"

namespace nirslam {
namespace {

using Clock = std::chrono::steady_clock;

// Poses with ground truth needed before the view is aligned to it: fewer cannot fix a Sim(3)
// reliably on a short, nearly straight start.
constexpr std::size_t kMinAlignmentPairs = 10;

std::string tracking_text(TrackingStatus status) {
  switch (status) {
    case TrackingStatus::Initialising: return "initialising";
    case TrackingStatus::Tracking: return "tracking";
    case TrackingStatus::Lost: return "lost";
    case TrackingStatus::NewSegment: return "new segment";
  }
  return "?";
}

}  // namespace

std::string_view to_string(PipelineMode mode) {
  switch (mode) {
    case PipelineMode::Quality: return "quality";
    case PipelineMode::Odometry: return "odometry";
    case PipelineMode::Calibrated: return "calibrated";
    case PipelineMode::Illuminated: return "illuminated";
    case PipelineMode::OdometryIlluminated: return "odometry-illuminated";
  }
  return "?";
}

std::vector<PipelineMode> pipeline_modes() {
  return {PipelineMode::Quality, PipelineMode::Odometry, PipelineMode::Calibrated, PipelineMode::Illuminated,
          PipelineMode::OdometryIlluminated};
}

std::optional<PipelineMode> parse_pipeline_mode(std::string_view name) {
  for (PipelineMode mode : pipeline_modes())
    if (name == to_string(mode)) return mode;
  return std::nullopt;
}

std::vector<PipelineMode> odometry_modes() {
  return {PipelineMode::Odometry, PipelineMode::Calibrated, PipelineMode::Illuminated};
}

bool runs_calibration(PipelineMode mode) {
  return mode == PipelineMode::Calibrated || mode == PipelineMode::Illuminated;
}

// calibration.lamp_halo: beam in effect (the illuminated mode; other modes keep the polynomial).
static bool halo_is_the_beam(const PipelineOptions& o) {
  return o.lamp_halo == LampHaloModel::Beam && o.mode == PipelineMode::Illuminated;
}
// The frames corrected with a lens vignette alone (held, or flat with lamp_halo: beam), the
// illuminated mode's lamp factor carrying the beam.
static bool odometry_carries_beam(const PipelineOptions& o) {
  if (o.mode != PipelineMode::Illuminated) return false;
  if (halo_is_the_beam(o)) return true;
  return !o.given_calibration_folder.empty() && o.beam_in_odometry &&
         o.given_calibration_holds == GivenCalibrationParts::Vignette;
}

std::optional<LampHaloModel> lamp_halo_model_from_string(const std::string& text) {
  if (text == "polynomial") return LampHaloModel::Polynomial;
  if (text == "beam") return LampHaloModel::Beam;
  return std::nullopt;
}

std::string_view to_string(LampDistanceSource source) {
  switch (source) {
    case LampDistanceSource::Neighbours: return "neighbours";
    case LampDistanceSource::Tracks: return "tracks";
    case LampDistanceSource::TracksElseNeighbours: return "tracks-else-neighbours";
    case LampDistanceSource::HeldNeighbours: return "held-neighbours";
    case LampDistanceSource::HeldTracks: return "held-tracks";
  }
  return "neighbours";
}

std::optional<LampDistanceSource> lamp_distance_source_from_string(std::string_view text) {
  for (const LampDistanceSource source :
       {LampDistanceSource::Neighbours, LampDistanceSource::Tracks, LampDistanceSource::TracksElseNeighbours,
        LampDistanceSource::HeldNeighbours, LampDistanceSource::HeldTracks})
    if (text == to_string(source)) return source;
  return std::nullopt;
}

bool corrects_illuminator(PipelineMode mode) {
  return mode == PipelineMode::Illuminated || mode == PipelineMode::OdometryIlluminated;
}

std::optional<std::string> lamp_distance_backfill_problem(const PipelineOptions& options) {
  if (!options.lamp_distance_backfill) return std::nullopt;
  if (options.lamp_distance_source != LampDistanceSource::Tracks && options.lamp_distance_source != LampDistanceSource::HeldTracks)
    return fmt::format("needs lamp_distance_source 'tracks' or 'held-tracks' (the track's own point), got '{}'",
                       to_string(options.lamp_distance_source));
  if (options.lamp_cosine_to_calibration && !options.lamp_cosine_held_per_track)
    return std::string("fills in the lamp's cosine from the normal held per track: with lamp_cosine_to_calibration it "
                       "needs lamp_cosine_held_per_track: true");
  return std::nullopt;
}

SlamPipeline::SlamPipeline(PipelineOptions options, std::shared_ptr<const CameraModel> camera,
                           std::optional<PhotometricTruth> truth)
    : options_(std::move(options)), camera_(std::move(camera)), truth_(std::move(truth)) {
  options_.odometry.illuminator_correction = corrects_illuminator(options_.mode);
  // The beam is radial in the image like the vignetting, so the calibration's halo factor holds
  // it and the corrected frames no longer show it: only raw frames need the beam term.
  if (options_.light_offset_estimation.beam_exponent < 0.0)
    options_.light_offset_estimation.beam_exponent = options_.odometry.beam_exponent;
  if (corrects_illuminator(options_.mode) && options_.lamp_distances_to_calibration) {
    options_.calibration.keyframes_follow_deformation = options_.lamp_mode_keyframes_follow_surface;
    options_.calibration.exposure.follow_deformation = options_.lamp_mode_exposure_follows_surface;
    options_.calibration.backend.vignette_rim_curvature_weight = options_.lamp_mode_vignette_rim_curvature_weight;
    options_.calibration.tracker.skip_coarse_levels_at_border = options_.lamp_mode_track_near_border;
    options_.calibration.tracker.min_reference_ncc = options_.lamp_mode_min_reference_ncc;
  }
  const bool given_calibration = runs_calibration(options_.mode) && !options_.given_calibration_folder.empty();
  const double configured_beam_exponent = options_.odometry.beam_exponent;
  // A given response with the beam: the lamp-lit response is weakly determined online (README
  // "Illuminator correction", session 41), one from a power or exposure sweep is not.
  if (halo_is_the_beam(options_) && given_calibration &&
      options_.given_calibration_holds != GivenCalibrationParts::Response)
    throw std::invalid_argument(
        "calibration.lamp_halo: beam estimates the halo factor, so with calibration.given only the response can be "
        "held (given_holds: response); for a given lens vignette use given_holds: vignette with estimate_beam and "
        "beam_in_odometry");
  if (runs_calibration(options_.mode)) {
    // An estimated halo factor holds the beam; a given lens vignette held alone does not.
    if (!odometry_carries_beam(options_) &&
        (!given_calibration || options_.given_calibration_holds != GivenCalibrationParts::Both))
      options_.odometry.beam_exponent = 0.0;
    options_.odometry.brightness_exponent = options_.corrected_frame_exponent;
  } else {
    options_.odometry.brightness_exponent = options_.raw_frame_exponent;
  }
  if (options_.beam_in_odometry && runs_calibration(options_.mode) && !halo_is_the_beam(options_) &&
      (!given_calibration || options_.given_calibration_holds != GivenCalibrationParts::Vignette))
    throw std::invalid_argument("calibration.beam_in_odometry needs the lens vignette held alone (calibration.given with given_holds: vignette)");
  if (given_calibration) hold_given_calibration(configured_beam_exponent);
  if (halo_is_the_beam(options_)) {
    if (!options_.calibration.given_part.empty()) options_.calibration.given_part += "; ";
    options_.calibration.given_part += "a flat lens (calibration.lamp_halo: beam; the lens's vignetting goes into the beam's m)";
    hold_lens_vignette(VignetteModel{}, configured_beam_exponent, true);
    spdlog::info("halo factor modelled as the lamp's beam alone: {}", options_.calibration.given_part);
  } else if (!given_calibration && options_.estimate_beam && runs_calibration(options_.mode))
    throw std::invalid_argument("calibration.estimate_beam needs a lens vignette given (calibration.given with given_holds: vignette)");
  if (const auto problem = lamp_distance_backfill_problem(options_))
    throw std::invalid_argument("pipeline.lamp_distance_backfill " + *problem);
  if (runs_calibration(options_.mode))
    calibration_ = std::make_unique<OnlinePhotometricCalibration>(options_.calibration);
  if (options_.mode == PipelineMode::Quality) {
    odometry_off_reason_ = "this pipeline mode has no odometry";
  } else if (!camera_) {
    odometry_off_reason_ = "no camera calibration for this source: odometry off";
  } else {
    if (camera_->type() == CameraModelType::Pinhole) {
      pinhole_ = std::make_unique<PinholeCamera>(camera_->width(), camera_->height(), camera_->intrinsics());
    } else {
      // Crop: every output pixel has a source pixel, so no artificial edges reach the odometry.
      pinhole_ = std::make_unique<PinholeCamera>(make_crop_pinhole(*camera_, camera_->width(), camera_->height()));
      undistorter_ = std::make_unique<Undistorter>(*camera_, *pinhole_);
    }
    odometry_ = std::make_unique<DirectOdometry>(*pinhole_, options_.odometry);
    if (calibration_ && !options_.lens_vignette_file.empty()) {
      lens_vignette_ = read_vignette_png(options_.lens_vignette_file);
      if (lens_vignette_.cols != camera_->width() || lens_vignette_.rows != camera_->height())
        throw InputError(options_.lens_vignette_file, fmt::format("the lens vignette is {}x{}, the camera {}x{}",
                                                                  lens_vignette_.cols, lens_vignette_.rows,
                                                                  camera_->width(), camera_->height()));
    }
    if (calibration_ && corrects_illuminator(options_.mode) && options_.lamp_distances_to_calibration)
      light_distances_ = std::make_unique<LightDistanceMap>(*camera_, options_.light_distances);
    const LampDistanceSource source = options_.lamp_distance_source;
    if (light_distances_ && (source == LampDistanceSource::Tracks || source == LampDistanceSource::TracksElseNeighbours ||
                             source == LampDistanceSource::HeldTracks))
      track_distances_ = std::make_unique<TrackLightDistances>(*camera_, options_.track_light_distances);
    if (light_distances_ && (source == LampDistanceSource::HeldNeighbours || source == LampDistanceSource::HeldTracks))
      track_points_ = std::make_unique<TrackLightPoints>(*camera_);
    if (light_distances_ && options_.lamp_cosine_to_calibration && options_.lamp_cosine_held_per_track) {
      track_cosines_ = std::make_unique<TrackLightCosines>(*camera_, options_.track_light_cosines);
      if (options_.lamp_cosine_normal_radius_px > 0.0) {
        LightDistanceMapOptions normals = options_.light_distances;
        normals.search_radius_px = options_.lamp_cosine_normal_radius_px;
        normal_map_ = std::make_unique<LightDistanceMap>(*camera_, normals);
      }
    }
    if (options_.lamp_distance_backfill && track_distances_) {
      KeyframeLightBackfillOptions backfill;
      backfill.min_cosine = options_.track_light_cosines.min_cosine;
      backfill_ = std::make_unique<KeyframeLightBackfill>(backfill);
    }
    if (light_distances_ && options_.estimate_light_offset && !options_.light_offset_configured)
      light_offset_ = std::make_unique<KeyframeLightOffset>(*pinhole_, options_.light_offset_estimation);
  }
}

SlamPipeline::~SlamPipeline() = default;

void SlamPipeline::hold_given_calibration(double beam_exponent) {
  const GivenCalibrationParts parts = options_.given_calibration_holds;
  if (options_.estimate_beam && parts != GivenCalibrationParts::Vignette)
    throw std::invalid_argument("calibration.estimate_beam needs the lens vignette held alone (calibration.given_holds: vignette)");
  const GivenPhotometricCalibration given = read_given_calibration(
      options_.given_calibration_folder, camera_ ? camera_->width() : 0, camera_ ? camera_->height() : 0, parts);
  PhotometricBackendOptions& backend = options_.calibration.backend;
  switch (parts) {
    case GivenCalibrationParts::Both:
      backend.initial_response = given.response;
      backend.initial_vignette = given.vignette;
      options_.calibration.given_model = given.description;
      spdlog::info("photometric calibration given: {}", given.description);
      return;
    case GivenCalibrationParts::Response:
      backend.initial_response = given.response;
      backend.estimate_response = false;
      options_.calibration.given_part = "response given: " + given.response_description;
      break;
    case GivenCalibrationParts::Vignette:
      options_.calibration.given_part = "lens vignette given: " + given.vignette_description;
      hold_lens_vignette(given.vignette, beam_exponent, options_.estimate_beam);
      break;
  }
  spdlog::info("photometric calibration partly given, the rest estimated online: {}", options_.calibration.given_part);
}

void SlamPipeline::hold_lens_vignette(const VignetteModel& lens, double beam_exponent, bool estimate_beam) {
  PhotometricBackendOptions& backend = options_.calibration.backend;
  backend.initial_vignette = lens;
  backend.estimate_vignette = false;
  if (estimate_beam) {
    if (!camera_) throw std::invalid_argument(
          "calibration.estimate_beam / lamp_halo: beam: the beam's angles need the camera's calibration");
    constexpr double kBeamStart = 2.0;  // cos(45 deg)^2 = 1/2
    backend.beam_halo = beam_halo_for_camera(*camera_, lens, beam_exponent > 0.0 ? beam_exponent : kBeamStart);
    backend.initial_vignette.v = backend.beam_halo->vignette(backend.beam_halo->initial_exponent());
    backend.estimate_vignette = true;
    options_.calibration.given_part +=
        fmt::format(" times the lamp's beam cos(alpha)^m, m estimated (from {:.2f})", backend.beam_halo->initial_exponent());
  } else if (beam_exponent > 0.0 && camera_) {
    // The lamp lights what the camera sees through its beam: the halo the frames show.
    const VignetteFit halo =
        fit_vignette_to_image(halo_with_beam(lens.render(camera_->width(), camera_->height()), *camera_, beam_exponent));
    if (halo.rms > kGivenVignetteMaxRms)
      throw InputError(options_.given_calibration_folder / "vignette.png",
                       fmt::format("this lens vignette times the lamp's beam cos(alpha)^{:.2f} fits nirslam's radial "
                                   "model only to {:.4f} rms (max {:.3f})",
                                   beam_exponent, halo.rms, halo.max));
    backend.initial_vignette = halo.vignette;
    options_.calibration.given_part +=
        fmt::format(" times the lamp's beam cos(alpha)^{:.2f} (fitted to {:.4f} rms)", beam_exponent, halo.rms);
  }
  if (odometry_carries_beam(options_)) {
    options_.calibration.correction_vignette = lens;
    options_.calibration.given_part += "; the frames corrected with the lens vignette alone, the odometry's lamp factor carries the beam";
  }
}

const PinholeCamera* SlamPipeline::odometry_camera() const { return odometry_ ? pinhole_.get() : nullptr; }

cv::Mat SlamPipeline::odometry_input(const Frame& frame, const cv::Mat& corrected) {
  cv::Mat grey;
  if (!corrected.empty()) {
    grey = corrected;
  } else {
    // Raw grey on the 0..255 scale whatever the bit depth, as the odometry's thresholds expect.
    frame.image.convertTo(float_buffer_, CV_32F, 255.0 / static_cast<double>(frame.max_value()));
    grey = float_buffer_;
  }
  if (!undistorter_) return grey;
  cv::Mat out;
  cv::remap(grey, out, undistorter_->map_x(), undistorter_->map_y(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  return out;
}

cv::Mat SlamPipeline::encode_irradiance(const cv::Mat& irradiance) {
  // 255 (E / 255)^gamma; E can pass 255 where V < 1, and interpolation can dip below 0.
  cv::max(irradiance, 0.0, encoded_buffer_);
  cv::pow(encoded_buffer_, options_.corrected_frame_exponent, encoded_buffer_);
  encoded_buffer_ *= std::pow(255.0, 1.0 - options_.corrected_frame_exponent);
  return encoded_buffer_;
}

PipelineFrameResult SlamPipeline::process(const Frame& frame) {
  PipelineFrameResult result;
  if (camera_ && (frame.width() != camera_->width() || frame.height() != camera_->height()))
    throw std::invalid_argument(fmt::format("{}: image is {}x{}, the camera calibration says {}x{}",
                                            frame.name.empty() ? fmt::format("frame {}", frame.index) : frame.name,
                                            frame.width(), frame.height(), camera_->width(), camera_->height()));
  if (frame.T_world_cam_truth) {
    const Eigen::Vector3d c = frame.T_world_cam_truth->translation();
    truth_positions_[frame.index] = c;
    truth_path_.push_back(c.cast<float>());
  }

  last_illuminator_power_w_ = frame.illuminator_power_w;
  if (calibration_) {
    const auto start = Clock::now();
    // The correction holds its model until the odometry has tracked for a while (see
    // PipelineOptions::hold_correction_frames).
    if (odometry_ && options_.hold_correction_frames >= 0)
      calibration_->hold_correction((odometry_started_ || !odometry_waits_for_model()) &&
                                    frames_tracking_ <= options_.hold_correction_frames);
    calibration_->follow_at_once(odometry_ && !odometry_started_ && odometry_waits_for_model());
    CorrectedFrame corrected;
    if (predict_light_distances()) {
      FrameIllumination illumination;
      // Held points: no per-frame lookup once a track has its point (a fresh lookup would break the ratio).
      if (options_.lamp_distance_source != LampDistanceSource::Tracks && !track_points_)
        illumination.light_distance_m = [this](const Eigen::Vector2d& pixel) { return light_distances_->light_distance(pixel); };
      if (track_points_) {
        track_points_->begin_frame(*predicted_T_world_cam_, last_pose_->segment);
        illumination.track_light_distance_m = [this](std::int64_t track_id, const Eigen::Vector2d& pixel) {
          return track_points_->light_distance(track_id, pixel, options_.odometry.light_offset, [&]() -> std::optional<double> {
            if (track_distances_)  // held-tracks: placed at the track's triangulation, once it has one
              return track_distances_->light_distance(track_id, *predicted_T_world_cam_, options_.odometry.light_offset);
            return light_distances_->light_distance(pixel);
          });
        };
      } else if (track_distances_)
        illumination.track_light_distance_m = [this](std::int64_t track_id, const Eigen::Vector2d&) {
          return track_distances_->light_distance(track_id, *predicted_T_world_cam_, options_.odometry.light_offset);
        };
      if (track_cosines_) {
        track_cosines_->begin_frame(*predicted_T_world_cam_, last_pose_->segment);
        illumination.track_light_cosine = [this](std::int64_t track_id, const Eigen::Vector2d& pixel) -> std::optional<double> {
          // The plane fit only for a track without a held normal.
          std::optional<LightGeometry> geometry;
          if (!track_cosines_->holds_normal(track_id)) geometry = (normal_map_ ? *normal_map_ : *light_distances_).light_geometry(pixel);
          // The distance the calibration takes for this patch (the track's own first).
          std::optional<double> distance;
          if (track_points_)
            distance = track_points_->held_light_distance(track_id, options_.odometry.light_offset);
          else if (track_distances_)
            distance = track_distances_->light_distance(track_id, *predicted_T_world_cam_, options_.odometry.light_offset);
          if (!distance && options_.lamp_distance_source != LampDistanceSource::Tracks &&
              options_.lamp_distance_source != LampDistanceSource::HeldTracks)
            distance = geometry ? std::optional<double>(geometry->distance) : light_distances_->light_distance(pixel);
          if (!distance) return std::nullopt;
          return track_cosines_->cosine(track_id, pixel, *distance, options_.odometry.light_offset,
                                        geometry ? geometry->plane_normal_cam : std::nullopt);
        };
      } else if (options_.lamp_cosine_to_calibration) {
        illumination.light_cosine = [this](const Eigen::Vector2d& pixel) -> std::optional<double> {
          const auto geometry = light_distances_->light_geometry(pixel);
          return geometry ? geometry->cosine : std::nullopt;
        };
      }
      corrected = calibration_->process(frame, illumination);
      if (backfill_) backfill_lamp_distances(frame, illumination, corrected.keyframe);
      result.light_distance_points = light_distances_->projected_points();
      light_distance_points_ = result.light_distance_points;
    } else {
      light_distance_points_ = 0;
      corrected = calibration_->process(frame);
    }
    result.timings.photometric_ms = ms_since(start);
    result.corrected = corrected.irradiance;
    ExposurePoint point;
    point.frame_index = frame.index;
    point.timestamp_s = frame.timestamp_s;
    point.estimated = corrected.exposure ? static_cast<float>(*corrected.exposure) : std::numeric_limits<float>::quiet_NaN();
    point.reference = frame.exposure_ms ? static_cast<float>(*frame.exposure_ms * frame.gain.value_or(1.0))
                                        : std::numeric_limits<float>::quiet_NaN();
    point.keyframe = corrected.keyframe;
    if (!calibration_->exposure_history().empty()) reported_exposure_scale_.add(calibration_->exposure_history().back());
    exposures_.push_back(point);
    if (exposures_.size() > options_.exposure_history)
      exposures_.erase(exposures_.begin(), exposures_.begin() + static_cast<std::ptrdiff_t>(exposures_.size() - options_.exposure_history));
    photometric_dirty_ = true;
    result.photometric = std::move(corrected);
  }

  if (odometry_ && !odometry_started_) {
    // odometry_waits_for_model_frames: the odometry's first frame is one corrected with a fitted model.
    const int version = calibration_ ? calibration_->correction_model_version() : 0;
    if (!odometry_waits_for_model() || version > 0) {
      odometry_started_ = true;
      if (odometry_waits_for_model())
        spdlog::info("odometry: starts at frame {}, the first corrected with a fitted photometric model (v{})", frame.index, version);
    } else if (++frames_waiting_for_model_ > options_.odometry_waits_for_model_frames) {
      odometry_started_ = true;
      spdlog::warn("odometry: starts at frame {} on the initial photometric model: no fitted model after {} frames "
                   "(the back end says: {})",
                   frame.index, options_.odometry_waits_for_model_frames, calibration_->estimate()->status);
    }
  }
  if (odometry_ && odometry_started_) {
    const auto start = Clock::now();
    OdometryFrame input;
    input.frame_index = frame.index;
    input.timestamp_s = frame.timestamp_s;
    input.image = odometry_input(frame, result.corrected);
    const cv::Mat irradiance = input.image;
    if (!result.corrected.empty() && options_.corrected_frame_exponent != 1.0) input.image = encode_irradiance(irradiance);
    // Exposure for the odometry's brightness model: as the camera reports it when it does (exact,
    // as DSO uses TUM monoVO's times.txt), else the calibration's estimate.
    if (calibration_ && options_.calibration.use_reported_exposures && frame.exposure_ms)
      input.exposure = *frame.exposure_ms * frame.gain.value_or(1.0);
    else if (result.photometric)
      input.exposure = result.photometric->exposure;
    input.illuminator_power_w = frame.illuminator_power_w;
    if (options_.lamp_factor_waits_for_response && calibration_) {
      const auto estimate = calibration_->estimate();
      input.lamp_factor_trusted = estimate->response_determined;
      if (input.lamp_factor_trusted != lamp_factor_trusted_) {
        lamp_factor_trusted_ = input.lamp_factor_trusted;
        if (lamp_factor_trusted_)
          spdlog::info("odometry: the lamp's factor from frame {} on, the response determined (photometric model v{})",
                       frame.index, estimate->model_version);
        else
          spdlog::info("odometry: frame {} without the lamp's factor until the response is fitted from exposure changes",
                       frame.index);
      }
    }
    if (odometry_carries_beam(options_) && calibration_)
      if (const auto estimate = calibration_->estimate(); estimate && estimate->beam_exponent)
        input.beam_exponent = *estimate->beam_exponent;
    result.timings.undistort_ms = ms_since(start);
    OdometryResult odometry = odometry_->process(input);
    if (backfill_) backfill_->place_keyframe(frame.index, odometry.T_world_cam, odometry.segment);
    // The initialiser's hand-over, with the wall time of its phases (README, "Speed").
    if (odometry.message.rfind("initialised with", 0) == 0) spdlog::info("odometry: {}", odometry.message);
    frames_tracking_ = odometry.status == TrackingStatus::Tracking ? frames_tracking_ + 1 : 0;
    result.timings.odometry_ms = odometry.timings.total_ms;
    result.timings.mapping_ms = odometry.timings.mapping_ms;
    update_trajectory(frame, odometry);
    remember_odometry(odometry);
    estimate_light_offset(input, irradiance, odometry);
    result.odometry = std::move(odometry);
  }
  return result;
}

bool SlamPipeline::odometry_waits_for_model() const {
  return calibration_ && options_.odometry_waits_for_model_frames > 0 && options_.calibration.run_backend &&
         options_.calibration.given_model.empty();
}

bool SlamPipeline::predict_light_distances() {
  predicted_T_world_cam_.reset();
  if (!light_distances_ || !last_pose_ || window_points_.empty()) return false;
  // Constant velocity: the frame about to come moves as the last one did.
  SE3 predicted = last_pose_->T_world_cam;
  if (previous_pose_ && previous_pose_->segment == last_pose_->segment)
    predicted = last_pose_->T_world_cam * (previous_pose_->T_world_cam.inverse() * last_pose_->T_world_cam);
  predicted_T_world_cam_ = predicted;
  light_distances_->build(window_points_, predicted, options_.odometry.light_offset);
  if (normal_map_) normal_map_->build(window_points_, predicted, options_.odometry.light_offset);
  return !light_distances_->empty();
}

void SlamPipeline::backfill_lamp_distances(const Frame& frame, const FrameIllumination& illumination, bool keyframe) {
  // The point a track's distances come from: its held one, else its triangulation.
  const auto point_of_track = [this](std::int64_t track_id) -> std::optional<Eigen::Vector3d> {
    if (track_points_) return track_points_->point_world(track_id);
    return track_distances_->point_world(track_id);
  };
  // With the cosine, the track's held normal.
  KeyframeLightBackfill::VectorOfTrack normal_of_track;
  if (track_cosines_)
    normal_of_track = [this](std::int64_t track_id) { return track_cosines_->normal_world(track_id); };
  const std::vector<TrackObservation>& tracks = calibration_->last_tracks();
  for (KeyframeIllumination& found :
       backfill_->resolve(last_pose_->segment, point_of_track, tracks, options_.odometry.light_offset, normal_of_track))
    calibration_->fill_unknown_illumination(found.frame_index, std::move(found.values));
  if (!keyframe) return;
  std::vector<std::int64_t> without_distance;
  for (const TrackObservation& track : tracks)
    if (!point_of_track(track.id) || (track_cosines_ && !track_cosines_->holds_normal(track.id)))
      without_distance.push_back(track.id);
  backfill_->add_keyframe(frame.index, lamp_power_w(illumination, frame.illuminator_power_w), std::move(without_distance));
}

void SlamPipeline::estimate_light_offset(const OdometryFrame& input, const cv::Mat& irradiance,
                                        const OdometryResult& result) {
  if (!light_offset_ || !result.is_keyframe || !result.T_world_cam) return;
  if (result.segment != light_offset_segment_) {
    // A new world frame and scale: what was estimated in the old one's units does not hold.
    light_offset_segment_ = result.segment;
    light_offset_estimate_.reset();
    if (options_.apply_estimated_light_offset) options_.odometry.light_offset.setZero();
  }
  const double exposure = input.exposure.value_or(1.0) * input.illuminator_power_w.value_or(1.0);
  light_offset_->add_keyframe(result.segment, *result.T_world_cam, irradiance, exposure);
  if (light_offset_->keyframes() < 3) return;  // fewer views fix nothing
  const Eigen::Vector3d start = light_offset_estimate_ && light_offset_estimate_->determined
                                    ? light_offset_estimate_->offset_cam
                                    : Eigen::Vector3d::Zero();
  light_offset_estimate_ = light_offset_->estimate(window_points_, start);
  if (options_.apply_estimated_light_offset && light_offset_estimate_->determined)
    options_.odometry.light_offset = light_offset_estimate_->offset_cam;
  photometric_dirty_ = true;
}

void SlamPipeline::fit_beam(const PhotometricEstimate& estimate) {
  beam_fit_version_ = estimate.model_version;
  if (estimate.model_version <= 0) return;  // the initial model says nothing of the lamp
  beam_fit_ = fit_beam_from_halo(estimate.vignette.render(lens_vignette_.cols, lens_vignette_.rows), lens_vignette_, *camera_);
  // The offset estimation models the beam from the lamp; without a configured exponent, this one.
  if (light_offset_ && beam_fit_->ok && options_.light_offset_estimation.beam_exponent == 0.0)
    light_offset_->set_beam_exponent(beam_fit_->beam_exponent);
}

void SlamPipeline::remember_odometry(const OdometryResult& result) {
  if (!light_distances_ && !light_offset_) return;
  if (!result.T_world_cam || (last_pose_ && last_pose_->segment != result.segment)) {
    // Lost or a new segment: its world frame is new, and the old points do not belong to it.
    last_pose_.reset();
    previous_pose_.reset();
    window_points_.clear();
    if (light_distances_) light_distances_->clear();
    if (normal_map_) normal_map_->clear();
    if (track_distances_) track_distances_->clear();
    if (track_cosines_) track_cosines_->clear();
    if (track_points_) track_points_->clear();
    if (backfill_) backfill_->clear();
    if (!result.T_world_cam) return;
  }
  previous_pose_ = last_pose_;
  last_pose_ = TrackedPose{result.frame_index, result.segment, *result.T_world_cam};
  if (track_distances_) track_distances_->add_frame(calibration_->last_tracks(), *result.T_world_cam, result.segment);
  // The window's points change only when a keyframe is made (or tracking starts).
  if (result.is_keyframe || window_points_.empty()) odometry_->active_points(window_points_);
}

void SlamPipeline::update_trajectory(const Frame&, const OdometryResult& result) {
  if (result.is_keyframe || !last_odometry_ || last_odometry_->status != result.status ||
      last_odometry_->segment != result.segment)
    trajectory_rebuild_ = true;
  last_odometry_ = result;
  trajectory_dirty_ = true;
}

void SlamPipeline::finish() {
  if (calibration_) {
    calibration_->finish();
    photometric_dirty_ = true;
  }
}

std::shared_ptr<const PhotometricView> SlamPipeline::photometric_view() {
  if (!photometric_dirty_ && photometric_view_) return photometric_view_;
  auto view = std::make_shared<PhotometricView>();
  view->enabled = calibration_ != nullptr;
  if (truth_) {
    view->true_response = truth_->response;
    view->true_vignette = truth_->vignette;
    view->true_halo = truth_->halo;
  }
  if (calibration_) {
    const std::shared_ptr<const PhotometricEstimate> estimate = calibration_->estimate();
    view->response = estimate->response;
    view->vignette = estimate->vignette;
    view->model_version = estimate->model_version;
    view->converged = estimate->converged;
    view->iterations = estimate->iterations;
    view->cost = estimate->cost;
    view->keyframes = estimate->keyframes;
    view->points = estimate->points;
    view->ambiguity = std::string(to_string(estimate->ambiguity)) +
                      (estimate->ambiguity_detail.empty() ? "" : ": " + estimate->ambiguity_detail);
    view->status = estimate->status;
    view->grey_low = estimate->grey_low;
    view->grey_high = estimate->grey_high;
    view->radius_high = estimate->radius_high;
    view->range_advice = online_grey_range_advice(*estimate);
    view->lamp_not_modelled = !corrects_illuminator(options_.mode) && last_illuminator_power_w_ && *last_illuminator_power_w_ > 0.0;
    if (light_distances_)
      view->lamp_term = light_distance_points_ > 0
                            ? fmt::format("lamp term: {} odometry points", light_distance_points_)
                            : "lamp term: waiting for the odometry's points";
    if (light_offset_estimate_) {
      const LightOffsetEstimate& e = *light_offset_estimate_;
      const Eigen::Vector3d sigma = e.sigma();
      view->lamp_offset = e.determined
          ? fmt::format("lamp offset ({:.3f}, {:.3f}, {:.3f}) +- ({:.3f}, {:.3f}, {:.3f}) from {} points{}",
                        e.offset_cam.x(), e.offset_cam.y(), e.offset_cam.z(), sigma.x(), sigma.y(), sigma.z(), e.points,
                        options_.apply_estimated_light_offset ? ", in use" : ", not applied")
          : "lamp offset: " + e.reason;
    }
    if (estimate->beam_exponent) {
      const double m = *estimate->beam_exponent;
      view->lamp_beam = m > 0.0 ? fmt::format("lamp beam cos^{:.2f} (half angle {:.1f} deg), estimated over {}", m,
                                              std::acos(std::pow(0.5, 1.0 / m)) * 180.0 / M_PI,
                                              halo_is_the_beam(options_) ? "a flat lens (the lens's vignetting in it)"
                                                                         : "the given lens vignette")
                                : fmt::format("lamp beam cos^{:.2f}: not darker off the axis", m);
    } else if (!lens_vignette_.empty()) {
      if (estimate->model_version != beam_fit_version_) fit_beam(*estimate);
      if (beam_fit_)
        view->lamp_beam = beam_fit_->ok ? fmt::format("lamp beam cos^{:.2f} (half angle {:.1f} deg) = halo / lens vignette",
                                                      beam_fit_->beam_exponent, beam_fit_->half_angle_deg)
                                        : "lamp beam: " + beam_fit_->reason;
    }
    const auto& history = calibration_->exposure_history();
    if (!history.empty()) {
      view->exposure_status = history.back().status == ExposureStatus::Estimated ? "estimated" : std::string();
      if (view->exposure_status.empty()) {
        switch (history.back().status) {
          case ExposureStatus::FirstFrame: view->exposure_status = "first frame (normalisation)"; break;
          case ExposureStatus::Restarted: view->exposure_status = "chain restarted"; break;
          case ExposureStatus::NoEstimateYet: view->exposure_status = "no estimate yet"; break;
          case ExposureStatus::BlackFrame: view->exposure_status = "black frame: last estimate kept"; break;
          case ExposureStatus::SaturatedFrame: view->exposure_status = "saturated frame: last estimate kept"; break;
          case ExposureStatus::TooFewTracks: view->exposure_status = "too few tracks: last estimate kept"; break;
          case ExposureStatus::NotFinite: view->exposure_status = "no finite estimate: last kept"; break;
          case ExposureStatus::Estimated: break;
        }
      }
      view->exposure_unit = history.front().reported ? "ms" : "relative";
    }
  }
  view->exposures = exposures_;
  const ReportedExposureScale scale = reported_exposure_scale_.current();
  view->exposure_scale = scale.factor;
  view->exposure_scale_frames = scale.frames;
  for (ExposurePoint& p : view->exposures)
    if (std::isfinite(p.estimated)) p.estimated = static_cast<float>(p.estimated * scale.factor);
  photometric_view_ = std::move(view);
  photometric_dirty_ = false;
  return photometric_view_;
}

PoseSample SlamPipeline::pose_sample(std::int64_t frame_index, double timestamp_s, int segment, const SE3& T_world_cam) const {
  PoseSample sample;
  sample.frame_index = frame_index;
  sample.timestamp_s = timestamp_s;
  sample.segment = segment;
  const SE3 pose = alignment_ ? alignment_->apply(T_world_cam) : T_world_cam;
  sample.position = pose.translation().cast<float>();
  sample.rotation = pose.unit_quaternion().cast<float>();
  if (alignment_) {
    const auto truth = truth_positions_.find(frame_index);
    if (truth != truth_positions_.end()) sample.error_m = static_cast<float>((pose.translation() - truth->second).norm());
  }
  return sample;
}

std::shared_ptr<TrajectoryView> SlamPipeline::rebuild_trajectory_view() {
  auto view = std::make_shared<TrajectoryView>();
  view->enabled = true;
  const std::vector<PoseStamped> trajectory = odometry_->trajectory();
  const int segment = last_odometry_ ? last_odometry_->segment : 0;

  // Align the current segment to the ground truth (Sim(3): monocular scale is arbitrary).
  alignment_.reset();
  if (!truth_positions_.empty()) {
    std::vector<Eigen::Vector3d> estimate;
    std::vector<Eigen::Vector3d> truth;
    for (const PoseStamped& p : trajectory) {
      if (p.segment != segment) continue;
      const auto t = truth_positions_.find(p.frame_index);
      if (t == truth_positions_.end()) continue;
      estimate.push_back(p.T_world_cam.translation());
      truth.push_back(t->second);
    }
    if (estimate.size() >= kMinAlignmentPairs && !alignment_degeneracy(estimate) && !alignment_degeneracy(truth)) {
      try {
        alignment_ = align_positions(estimate, truth, AlignmentMode::Sim3).transform;
      } catch (const std::exception& e) {
        spdlog::debug("trajectory view: no alignment to ground truth ({})", e.what());
      }
    }
  }
  view->aligned_to_ground_truth = alignment_.has_value();
  if (alignment_) view->ground_truth = truth_path_;

  view->poses.reserve(trajectory.size());
  double squared_error = 0.0;
  int errors = 0;
  for (const PoseStamped& p : trajectory) {
    view->poses.push_back(pose_sample(p.frame_index, p.timestamp_s, p.segment, p.T_world_cam));
    const PoseSample& s = view->poses.back();
    if (s.error_m >= 0.0f && s.segment == segment) {
      squared_error += static_cast<double>(s.error_m) * s.error_m;
      ++errors;
    }
  }
  if (errors > 0) view->ate_rmse_m = std::sqrt(squared_error / errors);
  for (const KeyframeState& k : odometry_->keyframes())
    view->keyframes.push_back(pose_sample(k.frame_index, k.timestamp_s, k.segment, k.T_world_cam));
  auto points = std::make_shared<std::vector<MapPointSample>>();
  const std::vector<MapPoint> map = odometry_->points();
  points->reserve(map.size());
  active_points_.clear();
  for (const MapPoint& p : map) {
    if (p.active) active_points_.push_back(p.p_world);
    const Eigen::Vector3d position = alignment_ ? alignment_->apply(p.p_world) : p.p_world;
    points->push_back({position.cast<float>(), p.intensity, p.active});
  }
  view->points = std::move(points);
  return view;
}

void SlamPipeline::project_active_points(TrajectoryView& view) const {
  view.current_pixels.clear();
  view.current_depths.clear();
  if (!last_odometry_ || !last_odometry_->T_world_cam || !camera_) return;
  const SE3 T_cam_world = last_odometry_->T_world_cam->inverse();
  view.current_pixels.reserve(active_points_.size());
  view.current_depths.reserve(active_points_.size());
  for (const Eigen::Vector3d& p_world : active_points_) {
    const Eigen::Vector3d p_cam = T_cam_world * p_world;
    if (p_cam.z() <= 0.0) continue;
    // The source's own model: the overlay lands on the raw (distorted) frame the feed shows.
    const auto pixel = camera_->project(p_cam);
    if (!pixel || !camera_->contains(*pixel)) continue;
    view.current_pixels.push_back(pixel->cast<float>());
    view.current_depths.push_back(static_cast<float>(p_cam.z()));
  }
}

std::shared_ptr<const TrajectoryView> SlamPipeline::trajectory_view() {
  if (!odometry_) {
    if (!trajectory_view_) {
      auto view = std::make_shared<TrajectoryView>();
      view->enabled = false;
      view->message = odometry_off_reason_;
      trajectory_view_ = std::move(view);
    }
    return trajectory_view_;
  }
  if (!trajectory_dirty_ && trajectory_view_) return trajectory_view_;

  std::shared_ptr<TrajectoryView> view;
  if (trajectory_rebuild_ || !trajectory_view_) {
    view = rebuild_trajectory_view();
    trajectory_rebuild_ = false;
  } else {
    // Between keyframes only the newest pose is new: copy the last view and append it.
    view = std::make_shared<TrajectoryView>(*trajectory_view_);
    if (last_odometry_ && last_odometry_->T_world_cam)
      view->poses.push_back(pose_sample(last_odometry_->frame_index, last_odometry_->timestamp_s, last_odometry_->segment,
                                        *last_odometry_->T_world_cam));
    if (view->aligned_to_ground_truth) view->ground_truth = truth_path_;
  }
  if (last_odometry_) {
    view->tracking = tracking_text(last_odometry_->status);
    view->message = last_odometry_->message;
    view->segment = last_odometry_->segment;
    view->current.reset();
    if (last_odometry_->T_world_cam)
      view->current = pose_sample(last_odometry_->frame_index, last_odometry_->timestamp_s, last_odometry_->segment,
                                  *last_odometry_->T_world_cam);
  }
  project_active_points(*view);
  double length = 0.0;
  for (std::size_t i = 1; i < view->poses.size(); ++i)
    if (view->poses[i].segment == view->poses[i - 1].segment)
      length += (view->poses[i].position - view->poses[i - 1].position).norm();
  view->path_length = length;
  trajectory_view_ = std::move(view);
  trajectory_dirty_ = false;
  return trajectory_view_;
}

}  // namespace nirslam
