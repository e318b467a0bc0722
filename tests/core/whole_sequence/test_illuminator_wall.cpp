// The rig approaches a wall lit only by its own lamp (the simulator's renderer: 1/d^2, the beam
// and cos(theta), the light 5 cm below the lens). Between the first (host) view and the closer
// ones, photometric residuals at the true poses and depths are biased without the lamp's factor
// (the wall brightens as the rig comes closer) and flat with it; with the factor, the coarse
// tracker also finds the approach better.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <span>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "nirslam/camera/camera_model.hpp"
#include "nirslam/odometry/coarse_tracker.hpp"
#include "nirslam/odometry/immature_point.hpp"
#include "nirslam/odometry/photometric_residual.hpp"
#include "nirslam/odometry/surface_normals.hpp"
#include "nirslam/odometry/window_optimizer.hpp"
#include "nirslam/sim/renderer.hpp"
#include "nirslam/sim/scene.hpp"

namespace nirslam::odometry {
namespace {

constexpr int kWidth = 320;
constexpr int kHeight = 240;
constexpr double kFocal = 240.0;
constexpr double kWallY = 4.0;  // the wall's face, world y (world z up)

// A painted wall, 12 m wide and 8 m high, facing -y.
std::shared_ptr<const sim::Scene> wall_scene() {
  auto scene = std::make_shared<sim::Scene>();
  scene->kind = sim::SceneKind::Room;
  scene->seed = 3;
  sim::Primitive wall;
  wall.shape = sim::Shape::Box;
  wall.lo = Eigen::Vector3f(-6.0f, static_cast<float>(kWallY), -4.0f);
  wall.hi = Eigen::Vector3f(6.0f, static_cast<float>(kWallY) + 0.3f, 4.0f);
  wall.side = sim::Material::PaintedWall;
  wall.seed = 11;
  scene->primitives.push_back(wall);
  return scene;
}

// T_world_cam looking along +y (camera x = world x, camera y = world -z) at `distance` from the
// wall, slightly off its centre line.
SE3 pose_at(double distance) {
  Eigen::Matrix3d R;
  R.col(0) = Eigen::Vector3d(1, 0, 0);
  R.col(1) = Eigen::Vector3d(0, 0, -1);
  R.col(2) = Eigen::Vector3d(0, 1, 0);
  return SE3(R, Eigen::Vector3d(0.2, kWallY - distance, 0.3));
}

struct WallSequence {
  std::vector<double> distances;
  std::vector<SE3> T_world_cam;
  std::vector<std::shared_ptr<const ImagePyramid>> images;  // 0..255-ish, the first frame's mean 60
  cv::Mat host_depth;
  sim::Illuminator lamp;
};

const WallSequence& wall_sequence() {
  static const WallSequence sequence = [] {
    WallSequence s;
    auto camera = std::make_shared<PinholeCamera>(kWidth, kHeight,
                                                  Eigen::Vector4d(kFocal, kFocal, 159.5, 119.5));
    const sim::Renderer renderer(wall_scene(), camera, 1);
    sim::Lighting lighting;  // the lamp alone: no ambient light, no sky
    s.lamp = lighting.illuminator;
    double scale = 0.0;
    for (int k = 0; k < 8; ++k) {
      const double d = 3.0 - 0.2 * k;
      const SE3 pose = pose_at(d);
      cv::Mat radiance;
      cv::Mat depth;
      renderer.render(std::span<const SE3>(&pose, 1), lighting, radiance, k == 0 ? &depth : nullptr);
      if (k == 0) {
        scale = 60.0 / cv::mean(radiance)[0];
        s.host_depth = depth;
      }
      cv::Mat image;
      radiance.convertTo(image, CV_32F, scale);
      s.distances.push_back(d);
      s.T_world_cam.push_back(pose);
      s.images.push_back(std::make_shared<const ImagePyramid>(image, 3));
    }
    return s;
  }();
  return sequence;
}

const LevelCamera kWallCamera{kFocal, kFocal, 159.5, 119.5, kWidth, kHeight};

// Textured pixels of the host with their true inverse depths.
std::vector<WindowPoint> host_points(const WallSequence& s) {
  std::vector<WindowPoint> points;
  const PyramidLevel& host = s.images[0]->level(0);
  for (int y = 8; y < kHeight - 8; y += 2) {
    for (int x = 8; x < kWidth - 8; x += 2) {
      const Eigen::Vector3f sample = host.data[static_cast<std::size_t>(y * host.width + x)];
      const float z = s.host_depth.at<float>(y, x);
      if (sample.tail<2>().norm() < 2.0f || !(z > 0.0f)) continue;
      WindowPoint p;
      p.pixel = Eigen::Vector2d(x, y);
      p.inverse_depth = 1.0 / z;
      p.host_intensity[4] = sample[0];
      points.push_back(p);
    }
  }
  return points;
}

// The host's grey values over a point's residual pattern.
void set_wall_pattern_intensities(const PyramidLevel& host, WindowPoint& p) {
  for (int k = 0; k < kPatternSize; ++k) {
    const auto& o = kPattern[static_cast<std::size_t>(k)];
    p.host_intensity[static_cast<std::size_t>(k)] =
        host.at(static_cast<int>(p.pixel.x()) + o[0], static_cast<int>(p.pixel.y()) + o[1])[0];
  }
}

// Least-squares slope of y over x.
double slope(const std::vector<double>& x, const std::vector<double>& y) {
  double mx = 0.0, my = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    mx += x[i];
    my += y[i];
  }
  mx /= static_cast<double>(x.size());
  my /= static_cast<double>(y.size());
  double sxy = 0.0, sxx = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
  }
  return sxy / sxx;
}

// Mean residual I_t(warp) - g I_h over the host's points, per target distance, at the true poses
// and depths (same exposure and power: the affine transfer is the identity).
std::vector<double> mean_residuals(const WallSequence& s, const std::vector<WindowPoint>& points,
                                   const LampGeometry& lamp, bool with_normals) {
  std::vector<double> means;
  for (std::size_t k = 1; k < s.images.size(); ++k) {
    const SE3 T_th = s.T_world_cam[k].inverse() * s.T_world_cam[0];
    double sum = 0.0;
    int n = 0;
    for (const WindowPoint& p : points) {
      ResidualJacobian out;
      const Eigen::Vector3d* normal = with_normals && p.normal ? &*p.normal : nullptr;
      if (!linearize_residual(kWallCamera, s.images[k]->level(0), T_th, T_th, p.pixel, p.inverse_depth,
                              p.host_intensity[4], AffineTransfer{}, out, lamp, normal))
        continue;
      sum += out.residual;
      ++n;
    }
    EXPECT_GT(n, 200) << "target " << k;
    means.push_back(sum / std::max(1, n));
  }
  return means;
}

TEST(IlluminatorWall, ResidualsWithTheLampFactorAreFlatWhereWithoutItTheyAreBiased) {
  const WallSequence& s = wall_sequence();
  std::vector<WindowPoint> points = host_points(s);
  std::printf("%zu host points\n", points.size());
  ASSERT_GT(points.size(), 500u);
  // Normals from the neighbouring points' depths, as the odometry gets them.
  estimate_surface_normals(kWallCamera, points);
  int with_normal = 0;
  const Eigen::Vector3d wall_normal(0.0, 0.0, -1.0);  // in the camera frame
  for (const auto& p : points) {
    if (!p.normal) continue;
    ++with_normal;
    EXPECT_GT(p.normal->dot(wall_normal), std::cos(2.0 * M_PI / 180.0));
  }
  EXPECT_GT(with_normal, static_cast<int>(0.75 * points.size()));

  const std::vector<double> distances(s.distances.begin() + 1, s.distances.end());
  const LampGeometry off{};
  const LampGeometry distance_only{true, s.lamp.offset_cam, 0.0};
  const LampGeometry full{true, s.lamp.offset_cam, s.lamp.beam_exponent()};
  const auto plain = mean_residuals(s, points, off, false);
  const auto by_distance = mean_residuals(s, points, distance_only, false);
  const auto corrected = mean_residuals(s, points, full, true);
  std::vector<WindowPoint> true_normals = points;
  for (auto& p : true_normals) p.normal = wall_normal;
  const auto corrected_true = mean_residuals(s, true_normals, full, true);
  const double slope_plain = slope(distances, plain);
  const double slope_distance = slope(distances, by_distance);
  const double slope_corrected = slope(distances, corrected);
  std::printf("mean residual vs distance [grey levels / m]: plain %.2f, 1/d^2 only %.2f, 1/d^2 + beam + cos %.2f\n",
              slope_plain, slope_distance, slope_corrected);
  for (std::size_t i = 0; i < distances.size(); ++i)
    std::printf("  %.1f m: plain %7.2f  1/d^2 %7.2f  full %6.2f\n", distances[i], plain[i], by_distance[i], corrected[i]);
  // Without the factor the wall brightens strongly as the rig approaches.
  EXPECT_LT(slope_plain, -40.0);
  EXPECT_GT(plain.back(), 50.0);
  // 1/d^2 alone over-corrects: off the axis, the approach also moves points out of the beam and
  // to more grazing light, so on raw frames the beam and cos(theta) matter as much.
  EXPECT_GT(slope_distance, 20.0);
  // With the beam and cos(theta) it is flat: what stays (a few grey levels, the same with the
  // true normals) is the renderer's texture detail, which grows as the wall comes closer.
  EXPECT_LT(std::abs(slope_corrected), 0.03 * std::abs(slope_plain));
  for (std::size_t i = 0; i < corrected.size(); ++i) {
    EXPECT_LT(std::abs(corrected[i]), 0.06 * plain.back()) << distances[i] << " m";
    // A fifth of the points get no normal (too few neighbours in a plane): cos(theta) is missing
    // for them, which the mean shows by a grey level or two.
    EXPECT_NEAR(corrected[i], corrected_true[i], 3.0) << "normals from neighbours vs the wall's, " << distances[i] << " m";
  }
}

TEST(IlluminatorWall, TrackerFindsTheApproachBetterWithTheLampFactor) {
  const WallSequence& s = wall_sequence();
  std::vector<WindowPoint> points = host_points(s);
  estimate_surface_normals(kWallCamera, points);
  std::vector<ReferencePoint> reference;
  for (const auto& p : points)
    reference.push_back({p.pixel, p.inverse_depth, p.normal ? *p.normal : Eigen::Vector3d::Zero()});
  const std::size_t last = 2;  // 2.6 m from the wall, 0.4 m closer than the host
  const SE3 truth = s.T_world_cam[last].inverse() * s.T_world_cam[0];
  auto track = [&](const LampGeometry& lamp) {
    CoarseTrackerOptions options;
    options.lamp = lamp;
    options.affine_a_prior = 1e-3;  // plain odometry: the affine brightness is free
    options.affine_b_prior = 1e-3;
    CoarseTracker tracker(make_level_cameras(kWallCamera, 3), options);
    tracker.set_reference(s.images[0], 0.0, 0.0, 1.0, reference);
    // Frame after frame against the host, each starting from the one before (as the odometry
    // between keyframes).
    TrackingEstimate e;
    e.T_frame_ref = SE3();
    for (std::size_t k = 1; k <= last; ++k) {
      e = tracker.track(*s.images[k], 1.0, e.T_frame_ref, e.affine_a, e.affine_b);
      EXPECT_TRUE(e.valid) << k;
    }
    return std::pair<double, double>((e.T_frame_ref.translation() - truth.translation()).norm(), e.rms);
  };
  const auto [error_plain, rms_plain] = track(LampGeometry{});
  const auto [error_lamp, rms_lamp] =
      track(LampGeometry{true, s.lamp.offset_cam, s.lamp.beam_exponent()});
  std::printf("tracking 0.4 m of approach: translation error %.4f m (rms %.2f) plain, %.4f m (rms %.2f) with the lamp\n",
              error_plain, rms_plain, error_lamp, rms_lamp);
  // The residuals fit far better; the pose a little (the affine brightness absorbs the mean
  // brightening, not its spread over the image).
  EXPECT_LT(rms_lamp, 0.6 * rms_plain);
  EXPECT_LT(error_lamp, error_plain);
}

struct WindowRun {
  double translation_error = 0.0;  // of the two closer views, summed [m]
  double energy = 0.0;
};

// The window (host 3.0 m, targets 2.8 and 2.6 m), poses perturbed, affine brightness free.
WindowRun optimise_wall_window(const LampGeometry& lamp) {
  const WallSequence& s = wall_sequence();
  std::vector<WindowPoint> points = host_points(s);
  estimate_surface_normals(kWallCamera, points);
  WindowOptions options;
  options.lamp = lamp;
  WindowOptimizer window(kWallCamera, options);
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 1.0);
  const std::size_t views[] = {0, 1, 2};
  for (std::size_t v : views) {
    WindowFrame f;
    f.id = static_cast<std::int64_t>(v);
    f.pyramid = s.images[v];
    Vector6d d = Vector6d::Zero();
    if (v > 0) {
      d.head<3>() = Eigen::Vector3d(noise(rng), noise(rng), noise(rng)) * 0.01;
      d.tail<3>() = Eigen::Vector3d(noise(rng), noise(rng), noise(rng)) * 0.002;
    } else {
      f.pose_prior_weight = 1e8;
      f.pose_prior = s.T_world_cam[v].inverse();
    }
    f.state.T_cam_world = SE3::exp(d) * s.T_world_cam[v].inverse();
    f.affine_a_prior_weight = 1.0;
    f.affine_b_prior_weight = 1.0;
    window.add_frame(std::move(f));
  }
  const PyramidLevel& host = s.images[0]->level(0);
  for (std::size_t i = 0; i < points.size(); i += 2) {
    WindowPoint p = points[i];
    set_wall_pattern_intensities(host, p);
    p.inverse_depth_prior_weight = 10.0;  // the scale gauge
    p.inverse_depth_prior_mean = p.inverse_depth;
    p.inverse_depth *= 1.0 + 0.05 * noise(rng);
    window.connect_to_all(p, 0);
    window.frames()[0].points.push_back(p);
  }
  const WindowStatistics stats = window.optimize(20);
  EXPECT_LT(stats.final_energy, stats.initial_energy);
  std::printf("  energy %.0f -> %.0f in %d iterations, %d residuals\n", stats.initial_energy, stats.final_energy,
              stats.iterations, stats.residuals);
  WindowRun run;
  run.energy = stats.final_energy;
  for (std::size_t k = 1; k < 3; ++k)
    run.translation_error +=
        (window.frames()[k].state.T_cam_world.inverse().translation() - s.T_world_cam[views[k]].translation()).norm();
  return run;
}

// With the lamp's factor (and its 9-parameter host/target mapping of the Hessian) the
// optimisation fits the views better and recovers the poses more closely (measured: energy
// 175k vs 269k, translation error 3.2 vs 4.4 cm; the rest is the renderer's texture detail).
TEST(IlluminatorWall, WindowOptimisationWithTheLampFactor) {
  const WallSequence& s = wall_sequence();
  const WindowRun plain = optimise_wall_window(LampGeometry{});
  const WindowRun lamp = optimise_wall_window(LampGeometry{true, s.lamp.offset_cam, s.lamp.beam_exponent()});
  std::printf("window: translation error %.4f m (energy %.0f) plain, %.4f m (energy %.0f) with the lamp\n",
              plain.translation_error, plain.energy, lamp.translation_error, lamp.energy);
  EXPECT_LT(lamp.energy, 0.8 * plain.energy);
  EXPECT_LT(lamp.translation_error, plain.translation_error);
}

// The window under a beam estimated too narrow (m 1.5 too high, as the back end's estimate in a
// garage with a glossy floor): with g's derivatives the brightness the wrong beam predicts pulls
// the poses along the approach (measured 23 cm); with g held at each linearisation
// (OdometryOptions::lamp_factor_derivatives_in_window false, the default) 7.8 cm.
TEST(IlluminatorWall, WindowHoldingTheLampFactorKeepsTheApproachUnderAWrongBeam) {
  const WallSequence& s = wall_sequence();
  LampGeometry with_derivatives{true, s.lamp.offset_cam, s.lamp.beam_exponent() + 1.5};
  LampGeometry held = with_derivatives;
  held.derivatives = false;
  const WindowRun pulled = optimise_wall_window(with_derivatives);
  const WindowRun kept = optimise_wall_window(held);
  LampGeometry truth{true, s.lamp.offset_cam, s.lamp.beam_exponent()};
  const WindowRun truth_with_derivatives = optimise_wall_window(truth);
  truth.derivatives = false;
  const WindowRun truth_held = optimise_wall_window(truth);
  std::printf("window under m + 1.5: translation error %.4f m with g's derivatives, %.4f m g held (true m: %.4f / "
              "%.4f m)\n",
              pulled.translation_error, kept.translation_error, truth_with_derivatives.translation_error,
              truth_held.translation_error);
  EXPECT_LT(kept.translation_error, 0.5 * pulled.translation_error);
  // The price: where the beam is right the derivatives place the views best (measured 3.2 cm
  // against 6.4 cm held). The pipeline's beam is estimated, 0.5-2 off its best value on Table 2's
  // sequences, and there holding wins (README "Illuminator correction", session 49).
  EXPECT_LT(truth_with_derivatives.translation_error, truth_held.translation_error);
}

// With the beam carried by the residual (frames corrected for the lens alone), lamp-lit
// residuals are those of beam-corrected frames times the target's B(alpha_t), so rim points
// weigh less. With beam-corrected weights the window sees the energy of beam-corrected frames.
TEST(IlluminatorWall, BeamCorrectedWeightsGiveTheEnergyOfBeamCorrectedFrames) {
  const WallSequence& s = wall_sequence();
  const double m = s.lamp.beam_exponent();
  // The light at the lens in both models, so the beam is a function of the pixel alone.
  auto beam_at_pixel = [&](int x, int y) {
    const Eigen::Vector3d ray = kWallCamera.unproject(Eigen::Vector2d(x, y));
    return std::pow(ray.z() / ray.norm(), m);
  };
  std::vector<std::shared_ptr<const ImagePyramid>> beam_corrected;
  double darkest_beam = 1.0;
  for (const auto& pyramid : s.images) {
    const PyramidLevel& level = pyramid->level(0);
    cv::Mat image(level.height, level.width, CV_32F);
    for (int y = 0; y < level.height; ++y)
      for (int x = 0; x < level.width; ++x) {
        image.at<float>(y, x) = static_cast<float>(level.at(x, y)[0] / beam_at_pixel(x, y));
        darkest_beam = std::min(darkest_beam, beam_at_pixel(x, y));
      }
    beam_corrected.push_back(std::make_shared<const ImagePyramid>(image, 3));
  }
  ASSERT_LT(darkest_beam, 0.35);  // the corners: the weighting matters there
  const std::vector<WindowPoint> points = host_points(s);
  auto window_energy = [&](const std::vector<std::shared_ptr<const ImagePyramid>>& images, const LampGeometry& lamp) {
    WindowOptions options;
    options.lamp = lamp;
    WindowOptimizer window(kWallCamera, options);
    for (std::size_t v = 0; v < 3; ++v) {
      WindowFrame f;
      f.id = static_cast<std::int64_t>(v);
      f.pyramid = images[v];
      f.state.T_cam_world = s.T_world_cam[v].inverse();
      window.add_frame(std::move(f));
    }
    const PyramidLevel& host = images[0]->level(0);
    for (std::size_t i = 0; i < points.size(); i += 2) {
      WindowPoint p = points[i];
      set_wall_pattern_intensities(host, p);
      window.connect_to_all(p, 0);
      window.frames()[0].points.push_back(p);
    }
    return window.energy();
  };
  LampGeometry distance_only{true, Eigen::Vector3d::Zero(), 0.0};
  LampGeometry beam_in_residual{true, Eigen::Vector3d::Zero(), m};
  const double energy_beam_corrected_frames = window_energy(beam_corrected, distance_only);
  const double energy_beam_weighted_as_lit = window_energy(s.images, beam_in_residual);
  beam_in_residual.beam_corrected_weights = true;
  const double energy_beam_weighted_as_corrected = window_energy(s.images, beam_in_residual);
  std::printf("window energy at the true poses: beam-corrected frames %.0f; beam in the residual %.0f, "
              "with beam-corrected weights %.0f\n",
              energy_beam_corrected_frames, energy_beam_weighted_as_lit, energy_beam_weighted_as_corrected);
  // Not equal to the bit: the corrected frames are interpolated after the division, and B is
  // taken at a pattern's centre.
  EXPECT_NEAR(energy_beam_weighted_as_corrected / energy_beam_corrected_frames, 1.0, 0.01);
  EXPECT_LT(energy_beam_weighted_as_lit, 0.8 * energy_beam_corrected_frames);

  // The tracker alike, started at the true pose 0.4 m closer: its residual rms in beam-corrected
  // grey levels either way.
  std::vector<ReferencePoint> reference;
  for (const auto& p : points) reference.push_back({p.pixel, p.inverse_depth, Eigen::Vector3d::Zero()});
  auto tracked_rms = [&](const std::vector<std::shared_ptr<const ImagePyramid>>& images, const LampGeometry& lamp) {
    CoarseTrackerOptions options;
    options.lamp = lamp;
    // An offset b would be in lit grey levels in one model and corrected ones in the other.
    options.affine_a_prior = 1e8;
    options.affine_b_prior = 1e8;
    CoarseTracker tracker(make_level_cameras(kWallCamera, 3), options);
    tracker.set_reference(images[0], 0.0, 0.0, 1.0, reference);
    const SE3 truth = s.T_world_cam[2].inverse() * s.T_world_cam[0];
    const TrackingEstimate e = tracker.track(*images[2], 1.0, truth, 0.0, 0.0);
    EXPECT_TRUE(e.valid);
    std::printf("  tracked: translation error %.4f m, a %.3g, b %.3g, rms %.3f\n",
                (e.T_frame_ref.translation() - truth.translation()).norm(), e.affine_a, e.affine_b, e.rms);
    return e.rms;
  };
  const double rms_beam_corrected_frames = tracked_rms(beam_corrected, distance_only);
  const double rms_beam_weighted_as_corrected = tracked_rms(s.images, beam_in_residual);
  std::printf("tracked rms: beam-corrected frames %.3f, beam in the residual with beam-corrected weights %.3f\n",
              rms_beam_corrected_frames, rms_beam_weighted_as_corrected);
  EXPECT_NEAR(rms_beam_weighted_as_corrected / rms_beam_corrected_frames, 1.0, 0.02);
}

// The immature points' epipolar search from the first view into the one 0.4 m closer, where the
// wall is about 1.3 times brighter: with the lamp's factor at each candidate's inverse depth the
// search matches where the texture does; with the frame pair's affine transfer alone the
// brightened patches are outliers or land off the true depth.
TEST(IlluminatorWall, EpipolarSearchWithTheLampFactorFindsTheTrueDepth) {
  const WallSequence& s = wall_sequence();
  const std::vector<WindowPoint> points = host_points(s);
  const SE3 T_th = s.T_world_cam[2].inverse() * s.T_world_cam[0];
  const LampGeometry full{true, s.lamp.offset_cam, s.lamp.beam_exponent()};
  struct Outcome {
    int traced = 0, good = 0, bracketed = 0;
  };
  const auto search = [&](const LampGeometry& lamp) {
    Outcome outcome;
    for (const WindowPoint& p : points) {
      // Away from the focus of expansion, where the approach moves the point several pixels.
      if ((p.pixel - Eigen::Vector2d(159.5, 119.5)).norm() < 50.0) continue;
      ImmaturePoint point(p.pixel.cast<int>(), s.images[0]->level(0));
      ++outcome.traced;
      if (point.trace(kWallCamera, s.images[2]->level(0), T_th, AffineTransfer{}, TraceOptions{}, lamp) !=
          TraceStatus::Good)
        continue;
      ++outcome.good;
      outcome.bracketed += p.inverse_depth >= point.inverse_depth_min() && p.inverse_depth <= point.inverse_depth_max();
    }
    return outcome;
  };
  const Outcome plain = search(LampGeometry{});
  const Outcome lit = search(full);
  std::printf("traced %d: without the lamp's factor %d good, %d around the true depth; with it %d good, %d around it\n",
              plain.traced, plain.good, plain.bracketed, lit.good, lit.bracketed);
  ASSERT_GT(lit.traced, 300);
  // 516 and 324 of 771 when written: the intervals are tight (the search's pixel error), and
  // cos(theta), left out of this search, shifts some matches by a fraction of a pixel.
  EXPECT_GT(lit.bracketed, static_cast<int>(0.6 * lit.traced));
  EXPECT_GT(lit.bracketed, plain.bracketed + lit.traced / 5);
}

}  // namespace
}  // namespace nirslam::odometry
