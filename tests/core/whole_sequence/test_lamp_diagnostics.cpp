// Where does the beam's exponent bias of the lamp-lit calibration come from? With the simulator's
// exact distances and cosines and the halo factor in the beam's own form (V_lens cos(alpha)^m,
// `calibration.beam_halo_exact`), the co-lit table still puts m about 0.2 above the simulator's
// (README, session 40). This diagnostic builds the back end's keyframes from the same tracks
// several ways and fits m to each, so the variant whose m comes out right says where the bias
// enters. Heavy (rendering), run only with NIRSLAM_PHOTOMETRIC_DIAG_LAMP set, e.g.
//   NIRSLAM_PHOTOMETRIC_DIAG_LAMP=tunnel nirslam_core_tests --gtest_filter=PhotometricAccuracy.DiagnoseLampObservations
// Variants (every third frame a keyframe, exposures reported, each track's factor log(P cos / d^2)
// from the true geometry at its centre, as the co-lit table's runs get it):
//   A  the image as the calibration samples it
//   B  the noise-free image of the same radiance, sampled the same way
//   C  exact grey from the rendered radiance at the tracked pixels (radiance-domain bilinear)
//   c  C on D's samples only (the surface points fixed at first sight and visible)
//   D  exact grey from the rendered radiance at the true projection of each pixel's surface point
//   F  the image (as A samples it) at the true projection of each pixel's surface point: the grid
//      following the surface exactly
//   P  exact grey from the lamp model itself at that surface point (the renderer's formula: the
//      lamp's own angle and distance to the point, its cosine there; no radiance map, no ambient)
//   p  P at the track's centre pixel only (whose distance and cosine are the track's factor)
//   M  exact grey from the back end's model (the track's factor at its centre, the beam's angle
//      from the tracked pixel's ray): a check that the fit recovers m from data that fit it
// A variant's m off the simulator's where the one before it is right puts the bias between the two.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "nirslam/photometric/beam_halo.hpp"
#include "nirslam/photometric/calibration_output.hpp"
#include "nirslam/photometric/illumination_factor.hpp"
#include "nirslam/photometric/online_calibration.hpp"
#include "nirslam/pipeline/slam_pipeline.hpp"
#include "nirslam/sim/simulator.hpp"
#include "core/bilinear_sample.hpp"
#include "photometric_sequences.hpp"

namespace nirslam {
namespace {

// No depth edge within `reach` pixels (the co-lit table's NIRSLAM_PHOTOMETRIC_SKIP_DEPTH_EDGES):
// the inverse depth's second difference along x, y and both diagonals under 2 % of it.
bool depth_smooth_at(const cv::Mat& depth, const Eigen::Vector2d& pixel, int reach) {
  const int x = static_cast<int>(std::lround(pixel.x())), y = static_cast<int>(std::lround(pixel.y()));
  if (x < reach || y < reach || x + reach >= depth.cols || y + reach >= depth.rows) return false;
  const double rho = 1.0 / depth.at<float>(y, x);
  for (const auto& [dx, dy] : {std::pair{1, 0}, std::pair{0, 1}, std::pair{1, 1}, std::pair{1, -1}}) {
    const double ahead = 1.0 / depth.at<float>(y + reach * dy, x + reach * dx);
    const double behind = 1.0 / depth.at<float>(y - reach * dy, x - reach * dx);
    if (!(std::abs(ahead + behind - 2.0 * rho) <= 0.02 * rho)) return false;
  }
  return true;
}

struct LampVariant {
  char name;
  const char* what;
  std::vector<PhotometricKeyframe> keyframes;
};

// A surface point under one back-end pixel of a track, fixed where the track was first seen.
struct AnchoredSurfacePoint {
  Eigen::Vector3d world = Eigen::Vector3d::Zero();
  double lamp_invariant = 0.0;  // L d^2 / (B(alpha) cos(theta)) from the first frame (albedo J0 / pi)
  double model_radiance = 0.0;  // the back end's L_p: G(I) / (e V_lens B_cam a) at the first frame
  bool ok = false;
};

struct LampBeamFit {
  double beam_exponent = 0.0;
  double response_mean_grey = 0.0;
};

LampBeamFit fit_lamp_beam(const LampVariant& v, const SimulatorOptions& o, const Simulator& sim, double true_m, bool estimate_response,
              double mu) {
  PhotometricBackendOptions b;
  b.initial_response = o.response;
  b.estimate_response = estimate_response;
  b.estimate_vignette = true;
  b.max_points = 100000;
  b.max_stored_keyframes = 400;
  b.gradient_mu = mu;
  b.lit_gradient_mu = mu;
  b.beam_halo = beam_halo_for_camera(*sim.camera(), o.vignette, true_m);
  b.initial_vignette.v = b.beam_halo->vignette(true_m);
  b.beam_halo_exact = true;
  PhotometricBackend backend(b);
  for (const auto& k : v.keyframes) backend.add_keyframe(k);
  const BackendStep s = backend.optimise(60, true);
  PhotometricGroundTruth truth;
  truth.response = o.response;
  const PhotometricErrors e = compare_with_ground_truth(backend.response(), backend.vignette(), {}, truth, o.width, o.height);
  std::printf("  %c %-58s f %s mu %5.2f: m %.3f (true %.3f)  response %5.2f grey  rms %.2f  pts %d\n", v.name, v.what,
              estimate_response ? "est " : "held", mu, backend.beam_exponent(), true_m, e.response_mean_grey, s.residual_rms,
              s.points);
  return {backend.beam_exponent(), e.response_mean_grey};
}

TEST(PhotometricAccuracy, DiagnoseLampObservations) {
  const char* env = std::getenv("NIRSLAM_PHOTOMETRIC_DIAG_LAMP");
  if (env == nullptr) GTEST_SKIP() << "set NIRSLAM_PHOTOMETRIC_DIAG_LAMP=room|outdoor|parking|tunnel";
  const std::string spec = env;
  sim::SceneKind scene = sim::SceneKind::Room;
  for (const sim::SceneKind k : {sim::SceneKind::Outdoor, sim::SceneKind::Parking, sim::SceneKind::Tunnel})
    if (spec.find(sim::to_string(k)) != std::string::npos) scene = k;
  // NIRSLAM_DIAG_LAMP_OFF: the constant-radiance sequence of the same scene (the drift figures
  // only; the fits need the lamp).
  const bool lamp_off = std::getenv("NIRSLAM_DIAG_LAMP_OFF") != nullptr;
  const SimulatorOptions o = lamp_off ? test_photometric::constant_radiance(scene, ResponsePreset::Gamma, 150)
                                      : test_photometric::co_lit(scene, ResponsePreset::Gamma, 150);
  SimulatorOptions clean_options = o;
  clean_options.noise = false;
  Simulator sim(o);
  const Simulator clean(clean_options);
  const auto camera = sim.camera();
  const double power_w = o.powers_w.front();
  const sim::Illuminator light = sim.lighting(lamp_off ? 50.0 : power_w).illuminator;
  const double true_m = light.beam_exponent();
  const BeamHalo halo = beam_halo_for_camera(*camera, o.vignette, true_m);
  const Eigen::Vector3d light_cam = o.light_offset_cam;

  PhotometricTrackerOptions tracker_options;
  tracker_options.skip_coarse_levels_at_border = PipelineOptions{}.lamp_mode_track_near_border;
  if (const char* m = std::getenv("NIRSLAM_DIAG_MIN_NCC")) tracker_options.min_reference_ncc = std::atof(m);
  if (const char* g = std::getenv("NIRSLAM_DIAG_PAIR_GAIN")) tracker_options.frame_pair_gain = std::atoi(g) != 0;
  // NIRSLAM_DIAG_FOLLOW: variant A's grids follow each track's deformation (the tracker's estimate).
  // NIRSLAM_DIAG_AFFINE: the tracker aligns each track's first patch under an affine warp, and
  // variant A's grids follow that warp.
  const bool affine = std::getenv("NIRSLAM_DIAG_AFFINE") != nullptr;
  const bool follow = affine || std::getenv("NIRSLAM_DIAG_FOLLOW") != nullptr;
  tracker_options.estimate_deformation = follow;
  tracker_options.align_reference_affine = affine;
  PhotometricTracker tracker(tracker_options);

  LampVariant A{'A', "image", {}}, B{'B', "noise-free image", {}}, C{'C', "rendered radiance @ tracked px", {}},
      Cd{'c', "rendered radiance @ tracked px, D's samples", {}}, F{'F', "image @ true projection", {}},
      D{'D', "rendered radiance @ true projection", {}}, P{'P', "lamp model @ surface point (no radiance map)", {}},
      Pc{'p', "lamp model @ surface point, centre pixels only", {}}, M{'M', "the back end's own model (check)", {}};
  std::map<std::int64_t, std::array<AnchoredSurfacePoint, kBackendPixels>> points;
  const double k_sens = o.sensitivity * 1e-3;
  const auto V_lens = [&](const Eigen::Vector2d& p) { return o.vignette(VignetteModel::radius(p.x(), p.y(), o.width, o.height)); };
  const auto B_cam = [&](const Eigen::Vector2d& p) {
    return std::exp(true_m * halo.log_cos(VignetteModel::radius(p.x(), p.y(), o.width, o.height)));
  };
  const auto exact_grey = [&](double e, double irradiance_at_sensor) {
    const double g = 255.0 * o.response(std::min(k_sens * e * irradiance_at_sensor, 1.0));
    return g > 0.03 * 255 && g < 0.97 * 255 ? static_cast<float>(g) : -1.0f;
  };
  // The lamp's angle off its axis, distance and incidence at a world point seen at `q` (camera pose T_world_cam).
  struct LampGeometry {
    double beam = 0.0, cosine = 0.0, distance = 0.0;
  };
  const auto lamp_at = [&](const SE3& T_world_cam, const Eigen::Vector3d& world, const Eigen::Vector2d& q) -> std::optional<LampGeometry> {
    const Eigen::Vector3d from_light = T_world_cam.inverse() * world - light_cam;
    const auto cosine = test_photometric::true_light_cosine(sim, T_world_cam, q);
    if (!cosine || !(*cosine > 0.02)) return std::nullopt;
    const double alpha = std::acos(std::clamp(from_light.normalized().z(), -1.0, 1.0));
    return LampGeometry{light.beam(alpha), *cosine, from_light.norm()};
  };

  // Per radius bin (0.1): the tracked pixel against the true projection of its surface point,
  // log(L(tracked) / L(true)) of the rendered radiance and the drift's radial component (px).
  std::array<double, 10> log_ratio_sum{}, radial_drift_sum{}, drift_sum{};
  std::array<int, 10> bin_count{};
  std::array<double, 10> centre_log_ratio_sum{}, centre_drift_sum{};
  std::array<int, 10> centre_count{};
  int index = 0;
  while (auto f = sim.next(true)) {
    const Frame& frame = f->frame;
    const TrackedFrame& tracked = tracker.process(frame);
    // Each track's factor at its centre, as the co-lit table hands it (true distance and cosine).
    std::vector<double> log_illumination(tracked.tracks.size(), std::nan(""));
    for (std::size_t i = 0; i < tracked.tracks.size(); ++i) {
      const Eigen::Vector2d& c = tracked.tracks[i].position;
      if (!depth_smooth_at(f->depth, c, 1)) continue;
      const auto cosine = test_photometric::true_light_cosine(sim, f->T_world_cam, c);
      if (!cosine || !(*cosine > 0.02)) continue;
      log_illumination[i] = lamp_off ? 0.0 : nirslam::log_illumination(power_w, sim.light_distance(f->depth, c), cosine);
    }
    // Fix the surface points of new tracks where they are first seen.
    for (std::size_t i = 0; i < tracked.tracks.size(); ++i) {
      const TrackObservation& t = tracked.tracks[i];
      if (points.count(t.id) != 0) continue;
      auto& slot = points[t.id];
      if (!std::isfinite(log_illumination[i])) continue;  // never usable: its first factor is unknown
      for (int k = 0; k < kBackendPixels; ++k) {
        AnchoredSurfacePoint& sp = slot[static_cast<std::size_t>(k)];
        const Eigen::Vector2d p = t.position + backend_pixel_offset(k);
        const auto ray = camera->unproject(p);
        if (!ray || !depth_smooth_at(f->depth, p, 1)) continue;
        const double z = bilinear(f->depth, p.x(), p.y());
        sp.world = f->T_world_cam * ((z / ray->z()) * *ray);
        const auto lamp = lamp_at(f->T_world_cam, sp.world, p);
        const double L = bilinear(f->radiance, p.x(), p.y());
        if (!lamp || !(L > 0.0)) continue;
        sp.lamp_invariant = L * lamp->distance * lamp->distance / (lamp->beam * lamp->cosine);
        sp.model_radiance = L / (B_cam(p) * std::exp(log_illumination[i]));
        sp.ok = true;
      }
    }
    const bool keyframe = index % 3 == 0 && tracked.tracks.size() >= 20;
    ++index;
    if (!keyframe) continue;
    const double e = test_photometric::reported_exposure(frame);
    const SE3 T_cam_world = f->T_world_cam.inverse();
    const PhotometricKeyframe ka = make_photometric_keyframe(tracked, frame.timestamp_s, e, true, 0.03, 0.97, lamp_off ? nullptr : &log_illumination, follow);
    const Frame clean_frame = clean.expose(f->radiance, *frame.exposure_ms, frame.gain.value_or(1.0), 0);
    cv::Mat clean_image;
    clean_frame.image.convertTo(clean_image, CV_32F, 1.0 / 255.0);
    cv::Mat image;
    frame.image.convertTo(image, CV_32F, 1.0 / 255.0);
    PhotometricKeyframe kb = ka, kc = ka, kcd = ka, kf = ka, kpc = ka, kd = ka, kp = ka, km = ka;
    std::map<std::int64_t, std::size_t> row_of;
    for (std::size_t i = 0; i < tracked.tracks.size(); ++i) row_of[tracked.tracks[i].id] = i;
    for (std::size_t j = 0; j < ka.observations.size(); ++j) {
      const std::int64_t id = ka.observations[j].track_id;
      const std::size_t row = row_of.at(id);
      const TrackObservation& t = tracked.tracks[row];
      PatchSamples samples;
      sample_patch(clean_image, t.position, samples);
      const auto& slot = points[id];
      for (int k = 0; k < kBackendPixels; ++k) {
        const auto kk = static_cast<std::size_t>(k);
        const int row_in_patch = kPatchRadius + (k / 3 - 1) * kBackendPixelPitch;
        const int col_in_patch = kPatchRadius + (k % 3 - 1) * kBackendPixelPitch;
        const float y = samples[static_cast<std::size_t>(row_in_patch * kPatchSide + col_in_patch)];
        kb.observations[j].grey[kk] = y > 0.03f && y < 0.97f ? 255.0f * y : -1.0f;
        const Eigen::Vector2d p = ka.observations[j].pixel(k);
        kc.observations[j].grey[kk] = exact_grey(e, V_lens(p) * bilinear(f->radiance, p.x(), p.y()));
        for (PhotometricKeyframe* k_variant : {&kcd, &kd, &kf, &kp, &kpc, &km}) k_variant->observations[j].grey[kk] = -1.0f;
        const AnchoredSurfacePoint& sp = slot[kk];
        if (!sp.ok) continue;
        km.observations[j].grey[kk] = exact_grey(e, V_lens(p) * sp.model_radiance * B_cam(p) * std::exp(log_illumination[row]));
        const Eigen::Vector3d in_cam = T_cam_world * sp.world;
        const auto q = camera->project(in_cam);
        if (!q || q->x() < 2 || q->y() < 2 || q->x() > o.width - 3 || q->y() > o.height - 3) continue;
        if (!(std::abs(bilinear(f->depth, q->x(), q->y()) - in_cam.z()) < 0.01 * in_cam.z())) continue;  // hidden
        kd.observations[j].grey[kk] = exact_grey(e, V_lens(p) * bilinear(f->radiance, q->x(), q->y()));
        kcd.observations[j].grey[kk] = kc.observations[j].grey[kk];
        {
          const float grey = 255.0f * bilinear_sample(image, q->x(), q->y());
          kf.observations[j].grey[kk] = grey > 0.03f * 255.0f && grey < 0.97f * 255.0f ? grey : -1.0f;
        }
        {
          const double r = VignetteModel::radius(p.x(), p.y(), o.width, o.height);
          const auto bin = static_cast<std::size_t>(std::min(9, static_cast<int>(r * 10)));
          const Eigen::Vector2d centre(0.5 * o.width, 0.5 * o.height);
          const Eigen::Vector2d drift = p - *q;
          log_ratio_sum[bin] += std::log(bilinear(f->radiance, p.x(), p.y()) / bilinear(f->radiance, q->x(), q->y()));
          radial_drift_sum[bin] += drift.dot((*q - centre).normalized());
          drift_sum[bin] += drift.norm();
          ++bin_count[bin];
          if (k == kBackendPixels / 2) {
            centre_log_ratio_sum[bin] += std::log(bilinear(f->radiance, p.x(), p.y()) / bilinear(f->radiance, q->x(), q->y()));
            centre_drift_sum[bin] += drift.norm();
            ++centre_count[bin];
          }
        }
        if (const auto lamp = lamp_at(f->T_world_cam, sp.world, *q))
          kp.observations[j].grey[kk] =
              exact_grey(e, V_lens(p) * sp.lamp_invariant * lamp->beam * lamp->cosine / (lamp->distance * lamp->distance));
        if (k == kBackendPixels / 2) kpc.observations[j].grey[kk] = kp.observations[j].grey[kk];
      }
    }
    for (const auto& [variant, built] : {std::pair{&A, &ka}, {&B, &kb}, {&C, &kc}, {&Cd, &kcd}, {&F, &kf}, {&D, &kd},
                                            {&P, &kp}, {&Pc, &kpc}, {&M, &km}})
      variant->keyframes.push_back(*built);
  }
  std::printf("%s: %zu keyframes, the simulator's beam exponent %.3f\n", spec.c_str(), A.keyframes.size(), true_m);
  std::printf("radius bin: count, mean log(L(tracked) / L(true)) %%, mean drift px, mean radial drift px (+ outward)\n");
  for (std::size_t b = 0; b < 10; ++b)
    if (bin_count[b] > 0)
      std::printf("  %.1f-%.1f: %6d  %+6.2f %%  %.2f px  %+.3f px   centre pixel: %+6.2f %%  %.2f px\n", 0.1 * static_cast<double>(b),
                  0.1 * static_cast<double>(b + 1), bin_count[b], 100.0 * log_ratio_sum[b] / bin_count[b], drift_sum[b] / bin_count[b],
                  radial_drift_sum[b] / bin_count[b], 100.0 * centre_log_ratio_sum[b] / std::max(centre_count[b], 1),
                  centre_drift_sum[b] / std::max(centre_count[b], 1));
  if (lamp_off) return;
  const char* which = std::getenv("NIRSLAM_DIAG_VARIANTS");
  const double mu = std::getenv("NIRSLAM_PHOTOMETRIC_LIT_MU") ? std::atof(std::getenv("NIRSLAM_PHOTOMETRIC_LIT_MU")) : 25.0;
  for (const LampVariant* v : {&M, &Pc, &P, &D, &Cd, &C, &F, &B, &A}) {
    if (which != nullptr && std::string(which).find(v->name) == std::string::npos) continue;
    const LampBeamFit held = fit_lamp_beam(*v, o, sim, true_m, false, mu);
    const LampBeamFit joint = fit_lamp_beam(*v, o, sim, true_m, true, mu);
    // The harness itself: data that fit the back end's model give back the simulator's beam.
    if (v == &M) {
      EXPECT_NEAR(held.beam_exponent, true_m, 0.01);
      EXPECT_NEAR(joint.beam_exponent, true_m, 0.01);
      EXPECT_LT(joint.response_mean_grey, 0.5);
    }
  }
}

}  // namespace
}  // namespace nirslam
