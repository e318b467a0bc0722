// The online photometric calibration's front end (issue 6): gain-robust KLT and the per-frame
// exposure estimate from tracked patches.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <stdexcept>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "nirslam/photometric/exposure_estimator.hpp"
#include "nirslam/photometric/illumination_factor.hpp"
#include "nirslam/photometric/photometric_tracker.hpp"
#include "nirslam/photometric/track_deformation.hpp"
#include "nirslam/sim/simulator.hpp"

namespace nirslam {
namespace {

// A smooth random texture in [0.1, 0.45] of full scale (so twice as bright still does not clip).
cv::Mat texture(int width, int height, unsigned seed) {
  cv::Mat noise(height, width, CV_32F);
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::UNIFORM, 0.0, 1.0);
  cv::GaussianBlur(noise, noise, cv::Size(0, 0), 2.0);
  double lo = 0.0, hi = 0.0;
  cv::minMaxLoc(noise, &lo, &hi);
  noise = (noise - lo) / (hi - lo) * 0.35 + 0.1;
  return noise;
}

// The texture shifted by `shift` (content at x moves to x + shift), times `gain`, as 16-bit grey.
cv::Mat shifted(const cv::Mat& base, const Eigen::Vector2d& shift, double gain) {
  cv::Mat moved;
  const cv::Mat M = (cv::Mat_<double>(2, 3) << 1, 0, shift.x(), 0, 1, shift.y());
  cv::warpAffine(base, moved, M, base.size(), cv::INTER_CUBIC, cv::BORDER_REFLECT);
  cv::Mat out;
  moved.convertTo(out, CV_16U, 65535.0 * gain);
  return out;
}

Frame make_frame(const cv::Mat& image, int bit_depth, std::int64_t index, std::optional<double> exposure_ms) {
  Frame f;
  f.image = image;
  f.bit_depth = bit_depth;
  f.index = index;
  f.exposure_ms = exposure_ms;
  return f;
}

TEST(PhotometricTracker, RecoversSubpixelShiftUnderGainChange) {
  const cv::Mat base = texture(240, 200, 7);
  const Eigen::Vector2d shift(1.37, -0.62);
  PhotometricTrackerOptions options;
  const cv::Mat image0 = shifted(base, Eigen::Vector2d::Zero(), 1.0);
  const auto pyramid0 = build_intensity_pyramid(image0, 16, options.pyramid_levels);
  for (const double gain : {0.5, 0.8, 1.25, 2.0}) {
    const auto pyramid1 = build_intensity_pyramid(shifted(base, shift, gain), 16, options.pyramid_levels);
    int tracked = 0;
    double worst = 0.0;
    for (int y = 40; y <= 160; y += 20)
      for (int x = 40; x <= 200; x += 20) {
        const Eigen::Vector2d from(x, y);
        const auto track = track_patch(pyramid0, pyramid1, from, from, options);
        ASSERT_TRUE(track.has_value()) << "gain " << gain << " at " << x << "," << y;
        worst = std::max(worst, (track->position - from - shift).norm());
        // Loose: bilinear resampling at a sub-pixel offset blurs the patch a little, which lowers
        // its contrast, and a is a contrast ratio (the exposure estimator does not use a).
        EXPECT_NEAR(track->brightness_gain, gain, 0.12 * gain);
        ++tracked;
      }
    EXPECT_LT(worst, 0.1) << "gain " << gain;
    std::printf("gain %.2f: %d patches, worst shift error %.4f px\n", gain, tracked, worst);
  }
}

// The texture as seen after an affine map about `from`: content at from + u moves to to + A u,
// times `gain` plus `bias` (float, fractions of full scale).
cv::Mat warped(const cv::Mat& base, const Eigen::Vector2d& from, const Eigen::Vector2d& to, const Eigen::Matrix2d& A,
               double gain, double bias) {
  const Eigen::Matrix2d inverse = A.inverse();
  const Eigen::Vector2d offset = from - inverse * to;  // destination x samples base at offset + A^-1 x
  const cv::Mat M = (cv::Mat_<double>(2, 3) << inverse(0, 0), inverse(0, 1), offset.x(), inverse(1, 0), inverse(1, 1), offset.y());
  cv::Mat out;
  cv::warpAffine(base, out, M, base.size(), cv::INTER_CUBIC | cv::WARP_INVERSE_MAP, cv::BORDER_REFLECT);
  return out * gain + bias;
}

TEST(PhotometricTracker, AlignsTheFirstPatchUnderAnAffineWarp) {
  const cv::Mat base = texture(240, 200, 11);
  PhotometricTrackerOptions options;
  const double angle = 0.08;
  // A zoom, a small rotation and a shear, as a tilted surface seen nearer.
  const Eigen::Matrix2d A = 1.3 * (Eigen::Matrix2d() << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle)).finished() *
                            (Eigen::Matrix2d() << 1.0, 0.06, 0.0, 0.95).finished();
  double worst_position = 0.0, worst_warp = 0.0;
  int aligned = 0;
  for (int y = 60; y <= 140; y += 20)
    for (int x = 60; x <= 180; x += 20) {
      const Eigen::Vector2d from(x, y), to = from + Eigen::Vector2d(2.3, -1.4);
      PatchSamples reference;
      ASSERT_TRUE(sample_patch(base, from, reference));
      const cv::Mat image = warped(base, from, to, A, 0.7, 0.05);
      // From where a frame-to-frame step leaves it: 0.8 px off, the warp not known yet.
      const auto result = align_patch_affine(image, reference, to + Eigen::Vector2d(0.8, -0.6), Eigen::Matrix2d::Identity(), options);
      ASSERT_TRUE(result.has_value()) << x << "," << y;
      worst_position = std::max(worst_position, (result->position - to).norm());
      worst_warp = std::max(worst_warp, (result->warp - A).cwiseAbs().maxCoeff());
      EXPECT_NEAR(result->gain, 0.7, 0.05);
      EXPECT_LT(result->residual_rms, 0.005);
      ++aligned;
    }
  std::printf("%d patches: worst position error %.4f px, worst warp entry error %.4f\n", aligned, worst_position, worst_warp);
  // Measured 0.056 px and 0.043 (converged: the same with 4x the iterations): the magnified image
  // is resampled (cubic) and then sampled bilinearly, the reference at whole pixels, so the two
  // are not the same function; 0.043 in W moves the back end's outer samples (3 px out) 0.13 px.
  EXPECT_LT(worst_position, 0.08);
  EXPECT_LT(worst_warp, 0.06);
}

// A camera approaching a textured wall: the image magnifies about its centre by 2.5 % a frame.
// Translation-only steps from frame to frame slide off the surface point as the patch grows; with
// each track's first patch aligned under an affine warp (align_reference_affine) the position
// stays on it and the warp is the magnification.
TEST(PhotometricTracker, FirstPatchAlignmentStaysOnTheSurfacePointAsTheImageMagnifies) {
  constexpr int kWidth = 320, kHeight = 240, kFrames = 16;
  const cv::Mat base = texture(kWidth, kHeight, 3);
  const Eigen::Vector2d centre(0.5 * (kWidth - 1), 0.5 * (kHeight - 1));
  const auto run = [&](bool align) {
    PhotometricTrackerOptions options;
    options.align_reference_affine = align;
    PhotometricTracker tracker(options);
    std::map<std::int64_t, Eigen::Vector2d> born;  // surface point = frame-0 position
    double sum = 0.0, warp_error = 0.0;
    int count = 0;
    for (int k = 0; k < kFrames; ++k) {
      const double zoom = std::pow(1.025, k);
      cv::Mat image;
      warped(base, centre, centre, zoom * Eigen::Matrix2d::Identity(), 1.0, 0.0).convertTo(image, CV_16U, 65535.0);
      const TrackedFrame& tracked = tracker.process(make_frame(image, 16, k, 1.0));
      for (const TrackObservation& t : tracked.tracks) {
        if (t.age == 0 && k == 0) born[t.id] = t.position;
        if (k != kFrames - 1 || born.count(t.id) == 0) continue;
        sum += (t.position - (centre + zoom * (born[t.id] - centre))).norm();
        if (align) warp_error = std::max(warp_error, (t.deformation - zoom * Eigen::Matrix2d::Identity()).cwiseAbs().maxCoeff());
        ++count;
      }
    }
    EXPECT_GT(count, 20) << (align ? "aligned" : "frame to frame");
    return std::pair{sum / std::max(count, 1), warp_error};
  };
  const auto [stepped, unused] = run(false);
  const auto [aligned, warp_error] = run(true);
  std::printf("after a %.2fx magnification, tracks born in frame 0: mean distance from their surface point %.3f px frame to "
              "frame, %.3f px with the first patch aligned (warp entries within %.4f)\n",
              std::pow(1.025, kFrames - 1), stepped, aligned, warp_error);
  EXPECT_LT(aligned, 0.1);
  EXPECT_LT(aligned, 0.5 * stepped);
  EXPECT_LT(warp_error, 0.02);
}

// Where the first patch no longer models the patch (here the surface's texture fades into
// another over ten frames, as a reflection or a shadow might change it) while each frame-to-frame
// step passes its checks, the track goes on as a new surface from there instead of ending.
TEST(PhotometricTracker, ATrackWhoseFirstPatchNoLongerAlignsStartsANewSurface) {
  constexpr int kWidth = 240, kHeight = 200, kFrames = 14;
  const cv::Mat before = texture(kWidth, kHeight, 21), after = texture(kWidth, kHeight, 22);
  PhotometricTrackerOptions options;
  options.align_reference_affine = true;
  PhotometricTracker tracker(options);
  std::map<std::int64_t, Eigen::Vector2d> born;
  int survivors = 0, on_a_new_surface = 0;
  for (int k = 0; k < kFrames; ++k) {
    const double t = std::min(k / 10.0, 1.0);
    cv::Mat image;
    cv::Mat((1.0 - t) * before + t * after).convertTo(image, CV_16U, 65535.0);
    const TrackedFrame& tracked = tracker.process(make_frame(image, 16, k, 1.0));
    for (const TrackObservation& track : tracked.tracks) {
      if (k == 0) born[track.id] = track.position;
      if (k != kFrames - 1 || born.count(track.id) == 0) continue;
      ++survivors;
      on_a_new_surface += track.surface > 0;
    }
  }
  std::printf("%zu tracks from frame 0: %d still tracked after the texture changed, %d of them on a new surface\n", born.size(),
              survivors, on_a_new_surface);
  // Measured 138 and 132 of 200 (frame to frame alone, without the alignment: 138 and none).
  EXPECT_GT(survivors, static_cast<int>(born.size()) / 2);
  EXPECT_GT(on_a_new_surface, survivors / 2);
}

// One gain for the frame pair (PhotometricTrackerOptions::frame_pair_gain): the images' mean ratio
// is the exposure ratio here, and held at it each patch fits its translation alone, as precisely
// as with its own gain and bias; the reported gain is the pair's.
TEST(PhotometricTracker, FramePairGainFollowsTheShiftWithOneGain) {
  const cv::Mat base = texture(240, 200, 7);
  const Eigen::Vector2d shift(1.37, -0.62);
  PhotometricTrackerOptions options;
  const auto pyramid0 = build_intensity_pyramid(shifted(base, Eigen::Vector2d::Zero(), 1.0), 16, options.pyramid_levels);
  const auto pyramid1 = build_intensity_pyramid(shifted(base, shift, 1.6), 16, options.pyramid_levels);
  const double pair_gain = frame_pair_gain(pyramid0, pyramid1);
  EXPECT_NEAR(pair_gain, 1.6, 0.01);
  EXPECT_NEAR(frame_pair_gain(pyramid1, pyramid0), 1.0 / pair_gain, 1e-9);
  double worst = 0.0;
  for (int y = 40; y <= 160; y += 20)
    for (int x = 40; x <= 200; x += 20) {
      const Eigen::Vector2d from(x, y);
      const auto track = track_patch(pyramid0, pyramid1, from, from, options, pair_gain);
      ASSERT_TRUE(track.has_value()) << x << "," << y;
      EXPECT_EQ(track->brightness_gain, pair_gain);
      EXPECT_EQ(track->brightness_bias, 0.0);
      EXPECT_LT(track->residual_rms, 0.01);
      worst = std::max(worst, (track->position - from - shift).norm());
    }
  EXPECT_LT(worst, 0.1);
  // Held at half the pair's gain, no patch is followed with a residual the tracker would keep.
  for (int y = 40; y <= 160; y += 20)
    for (int x = 40; x <= 200; x += 20) {
      const Eigen::Vector2d from(x, y);
      const auto wrong = track_patch(pyramid0, pyramid1, from, from, options, 0.5 * pair_gain);
      EXPECT_TRUE(!wrong || wrong->residual_rms > options.max_residual_rms) << x << "," << y;
    }
}

// Drawn shapes on a mid-grey background, blurred a little as a lens would: a bright square (its
// corner is a corner at every level, its edge's middle at none), and a small dark dot 7 px from
// a long straight edge, which is a corner to a 9 x 9 patch at full resolution while the coarse
// levels, where the patch spans 36 x 36 px, see mostly the edge.
cv::Mat shapes() {
  cv::Mat image(200, 240, CV_32F, cv::Scalar(0.4f));
  cv::rectangle(image, cv::Rect(40, 60, 70, 70), cv::Scalar(0.8f), cv::FILLED);
  cv::rectangle(image, cv::Rect(167, 0, 73, 200), cv::Scalar(0.7f), cv::FILLED);
  cv::rectangle(image, cv::Rect(159, 99, 3, 3), cv::Scalar(0.1f), cv::FILLED);
  cv::GaussianBlur(image, image, cv::Size(0, 0), 0.8);
  cv::Mat out;
  image.convertTo(out, CV_16U, 65535.0);
  return out;
}

TEST(PhotometricTracker, CornerIsotropyTellsCornersFromEdgesAtEveryLevel) {
  PhotometricTrackerOptions options;
  const auto pyramid = build_intensity_pyramid(shapes(), 16, options.pyramid_levels);
  const double square_corner = corner_isotropy(pyramid, {40.0, 60.0});
  const double square_edge = corner_isotropy(pyramid, {75.0, 60.0});
  const double dot_by_edge = corner_isotropy(pyramid, {160.0, 100.0});
  const double flat = corner_isotropy(pyramid, {150.0, 180.0});
  const double outside = corner_isotropy(pyramid, {2.0, 100.0});
  // The dot by an edge alone at full resolution.
  const double dot_by_edge_fine = corner_isotropy(std::vector<cv::Mat>{pyramid[0]}, {160.0, 100.0});
  std::printf("isotropy: square corner %.3f, edge %.4f, dot by an edge %.3f (full resolution alone %.3f), flat %.3f\n",
              square_corner, square_edge, dot_by_edge, dot_by_edge_fine, flat);
  EXPECT_GT(square_corner, 0.5);
  EXPECT_LT(square_edge, 0.01);
  EXPECT_GT(dot_by_edge_fine, 0.1);
  EXPECT_LT(dot_by_edge, 0.5 * dot_by_edge_fine);
  EXPECT_EQ(flat, 0.0);
  EXPECT_EQ(outside, 0.0);

  // Detection keeps only corners at or above the bound; the dot by the edge is not one of them.
  const auto detect = [&](double min_isotropy) {
    PhotometricTrackerOptions o;
    o.min_corner_isotropy = min_isotropy;
    PhotometricTracker tracker(o);
    return tracker.process(make_frame(shapes(), 16, 0, std::nullopt)).tracks;
  };
  const auto near_dot = [](const TrackObservation& t) { return (t.position - Eigen::Vector2d(160.0, 100.0)).norm() < 4.0; };
  const auto all = detect(0.0);
  EXPECT_TRUE(std::any_of(all.begin(), all.end(), near_dot));
  const auto isotropic = detect(0.5 * (dot_by_edge + dot_by_edge_fine));
  ASSERT_FALSE(isotropic.empty());
  EXPECT_LT(isotropic.size(), all.size());
  EXPECT_FALSE(std::any_of(isotropic.begin(), isotropic.end(), near_dot));
  for (const TrackObservation& t : isotropic) EXPECT_GE(corner_isotropy(pyramid, t.position), 0.5 * (dot_by_edge + dot_by_edge_fine));
}

// The caller's detection mask: new corners only where it is nonzero; a mask of the wrong size or
// type is refused.
TEST(PhotometricTracker, DetectsNewCornersOnlyWhereTheCallerAllows) {
  const cv::Mat image = shifted(texture(240, 200, 3), Eigen::Vector2d::Zero(), 1.0);
  cv::Mat left_half(image.size(), CV_8UC1, cv::Scalar(0));
  left_half.colRange(0, 120).setTo(7);  // any nonzero value allows
  PhotometricTracker everywhere, masked;
  const auto all = everywhere.process(make_frame(image, 16, 0, std::nullopt)).tracks;
  const auto left = masked.process(make_frame(image, 16, 0, std::nullopt), left_half).tracks;
  ASSERT_GT(all.size(), 40u);
  ASSERT_GT(left.size(), 10u);
  EXPECT_TRUE(std::any_of(all.begin(), all.end(), [](const TrackObservation& t) { return t.position.x() >= 120.0; }));
  for (const TrackObservation& t : left) EXPECT_LT(t.position.x(), 120.0);
  PhotometricTracker refusing;
  EXPECT_THROW(refusing.process(make_frame(image, 16, 0, std::nullopt), cv::Mat(10, 10, CV_8UC1, cv::Scalar(255))),
               std::invalid_argument);
  EXPECT_THROW(refusing.process(make_frame(image, 16, 0, std::nullopt), cv::Mat(image.size(), CV_32FC1, cv::Scalar(1.0f))),
               std::invalid_argument);
}

// Patches 7-18 px from the border, where the coarsest level (a quarter of the resolution) has no
// room for the patch: ended without the option, refined from the finer levels with it.
TEST(PhotometricTracker, PatchesNearTheBorderAreTrackedFromTheFinerLevels) {
  const cv::Mat base = texture(240, 200, 5);
  const Eigen::Vector2d shift(1.21, -0.83);
  PhotometricTrackerOptions options;
  ASSERT_EQ(options.pyramid_levels, 3);
  const auto pyramid0 = build_intensity_pyramid(shifted(base, Eigen::Vector2d::Zero(), 1.0), 16, options.pyramid_levels);
  const auto pyramid1 = build_intensity_pyramid(shifted(base, shift, 1.3), 16, options.pyramid_levels);
  std::vector<Eigen::Vector2d> near_border;
  for (const double d : {7.0, 10.0, 14.0, 18.0}) {
    near_border.emplace_back(d, 100.0);          // left
    near_border.emplace_back(239.0 - d, 80.0);   // right
    near_border.emplace_back(120.0, d);          // top
    near_border.emplace_back(60.0, 199.0 - d);   // bottom
    near_border.emplace_back(d, d);              // corner
    near_border.emplace_back(239.0 - d, 199.0 - d);
  }
  for (const Eigen::Vector2d& from : near_border)
    EXPECT_FALSE(track_patch(pyramid0, pyramid1, from, from, options).has_value()) << from.transpose();
  options.skip_coarse_levels_at_border = true;
  double worst = 0.0;
  for (const Eigen::Vector2d& from : near_border) {
    const auto track = track_patch(pyramid0, pyramid1, from, from, options);
    ASSERT_TRUE(track.has_value()) << from.transpose();
    worst = std::max(worst, (track->position - from - shift).norm());
    EXPECT_NEAR(track->brightness_gain, 1.3, 0.15);
  }
  // 0.03-0.08 px along the edges, 0.11 at the corner pixel (7, 7); inside, 0.02-0.08.
  EXPECT_LT(worst, 0.15);
  // Inside, where every level fits, the option changes nothing.
  const Eigen::Vector2d inside(120.0, 100.0);
  const auto with = track_patch(pyramid0, pyramid1, inside, inside, options);
  options.skip_coarse_levels_at_border = false;
  const auto without = track_patch(pyramid0, pyramid1, inside, inside, options);
  ASSERT_TRUE(with && without);
  EXPECT_EQ(with->position, without->position);
}

TEST(PhotometricTracker, TracksSurviveAnExposureStep) {
  const cv::Mat base = texture(320, 240, 11);
  PhotometricTracker tracker;
  const TrackedFrame first = tracker.process(make_frame(shifted(base, Eigen::Vector2d(0.0, 0.0), 1.0), 16, 0, 10.0));
  ASSERT_GE(static_cast<int>(first.tracks.size()), tracker.options().min_tracks);
  const TrackedFrame& second = tracker.process(make_frame(shifted(base, Eigen::Vector2d(2.3, 1.1), 1.8), 16, 1, 18.0));
  int survived = 0;
  const Eigen::Vector2d shift(2.3, 1.1);
  for (const TrackObservation& t : second.tracks) {
    if (t.age != 1) continue;
    ++survived;
    const auto before = std::find_if(first.tracks.begin(), first.tracks.end(),
                                     [&](const TrackObservation& o) { return o.id == t.id; });
    ASSERT_NE(before, first.tracks.end());
    EXPECT_LT((t.position - before->position - shift).norm(), 0.1);
    EXPECT_NEAR(t.brightness_gain, 1.8, 0.2);
  }
  EXPECT_GE(survived, static_cast<int>(0.7 * static_cast<double>(first.tracks.size())));
}

// Every track of a frame is either followed into the next or counted once, with the check it
// failed first (TrackedFrame::ended). On a plain shift the only tracks that end are the patch
// searches that fail: corners found nearer the border than the coarsest pyramid level can
// sample (detection keeps kPatchRadius + 2 px clear, the level with a quarter of the resolution
// needs about 4 (kPatchRadius + 1); PhotometricTrackerOptions::skip_coarse_levels_at_border
// follows them from the finer levels instead). On a frame of another texture most tracks end.
TEST(PhotometricTracker, TrackEndsSayWhyTracksWereDropped) {
  const cv::Mat base = texture(320, 240, 11);
  const auto lost = [](const TrackedFrame& before, const TrackedFrame& after) {
    std::vector<Eigen::Vector2d> positions;
    for (const TrackObservation& o : before.tracks)
      if (std::none_of(after.tracks.begin(), after.tracks.end(), [&](const TrackObservation& t) { return t.id == o.id; }))
        positions.push_back(o.position);
    return positions;
  };
  PhotometricTracker tracker;
  const TrackedFrame first = tracker.process(make_frame(shifted(base, Eigen::Vector2d(0.0, 0.0), 1.0), 16, 0, 10.0));
  EXPECT_EQ(first.ended.total(), 0);  // nothing to follow yet
  const TrackedFrame second = tracker.process(make_frame(shifted(base, Eigen::Vector2d(1.5, 0.5), 1.0), 16, 1, 10.0));
  const std::vector<Eigen::Vector2d> lost_on_shift = lost(first, second);
  EXPECT_EQ(second.ended.total(), static_cast<int>(lost_on_shift.size()));
  EXPECT_EQ(second.ended.not_found, second.ended.total());
  constexpr double kCoarseMargin = 4.0 * (kPatchRadius + 1) + 4.0;  // + the shift and rounding
  for (const Eigen::Vector2d& p : lost_on_shift)
    EXPECT_TRUE(p.x() < kCoarseMargin || p.y() < kCoarseMargin || p.x() > 319 - kCoarseMargin || p.y() > 239 - kCoarseMargin)
        << p.transpose();
  PhotometricTrackerOptions near_border;
  near_border.skip_coarse_levels_at_border = true;
  PhotometricTracker border_tracker(near_border);
  border_tracker.process(make_frame(shifted(base, Eigen::Vector2d(0.0, 0.0), 1.0), 16, 0, 10.0));
  EXPECT_LT(border_tracker.process(make_frame(shifted(base, Eigen::Vector2d(1.5, 0.5), 1.0), 16, 1, 10.0)).ended.total(),
            second.ended.total() / 4);
  const TrackedFrame third = tracker.process(make_frame(shifted(texture(320, 240, 12), Eigen::Vector2d(0.0, 0.0), 1.0), 16, 2, 10.0));
  EXPECT_EQ(third.ended.total(), static_cast<int>(lost(second, third).size()));
  EXPECT_GT(third.ended.total(), static_cast<int>(0.7 * static_cast<double>(second.tracks.size())))
      << "not found " << third.ended.not_found << ", residual " << third.ended.residual << ", forward-backward "
      << third.ended.forward_backward << ", reference " << third.ended.reference;
}

// The drift check (PhotometricTrackerOptions::min_reference_ncc): a patch whose content slowly
// turns into another (as a patch sliding along an edge or following an occlusion corner does)
// passes every frame-to-frame test but is dropped once it no longer correlates with its first
// patch; a patch that only moves and changes brightness is kept.
TEST(PhotometricTracker, DriftCheckDropsTracksWhoseContentChanged) {
  const cv::Mat base = texture(320, 240, 11);
  const cv::Mat other = texture(320, 240, 12);
  const auto run = [&](double ncc, bool morph) {
    PhotometricTrackerOptions options;
    options.min_reference_ncc = ncc;
    PhotometricTracker tracker(options);
    std::int64_t first_ids = 0;
    int survivors = 0;
    for (int i = 0; i <= 10; ++i) {
      const double t = morph ? 0.1 * i : 0.0;  // fraction of the other texture
      const cv::Mat blend = (1.0 - t) * base + t * other;
      const TrackedFrame& f = tracker.process(make_frame(shifted(blend, Eigen::Vector2d(0.4 * i, 0.2 * i), 1.0 + 0.08 * i), 16, i, 10.0));
      if (i == 0) first_ids = static_cast<std::int64_t>(f.tracks.size());
      if (i == 10)
        for (const TrackObservation& o : f.tracks) survivors += o.id < first_ids;
    }
    return static_cast<double>(survivors) / static_cast<double>(first_ids);
  };
  // Measured (this test's printout): without the check 75 % of the first frame's tracks survive
  // the morph (the others leave the image or fail the frame-to-frame tests); with
  // min_reference_ncc 0.9, 1 %; a shift and gain ramp without the morph keeps 75 % with the check.
  const double kept_unchecked = run(0.0, true), kept_checked = run(0.9, true), kept_plain = run(0.9, false);
  std::printf("morph: kept %.2f without, %.2f with the drift check; shift + gain only: %.2f\n", kept_unchecked, kept_checked,
              kept_plain);
  EXPECT_GT(kept_unchecked, 0.6);
  EXPECT_LT(kept_checked, 0.1);
  EXPECT_GT(kept_plain, 0.6);
}

struct ExposureErrors {
  double median = 0.0;
  double max = 0.0;
  double exposure_min = 0.0;
  double exposure_max = 0.0;
  int estimated = 0;
};

// Runs tracker + estimator on a simulated sequence; relative error of the estimated exposure x gain
// against the simulator's, with the first frame normalised to the reported value.
// With `light_factor`, each track's log(P / d^2) from the simulator's true depths goes to the
// estimator (illumination_factor.hpp), which then also divides by the halo factor V B.
ExposureErrors run_sequence(const SimulatorOptions& options, bool light_factor = false) {
  Simulator sim(options);
  PhotometricTracker tracker;
  ExposureEstimator estimator(options.response, light_factor ? sim.halo_factor() : options.vignette);
  std::vector<double> errors, log_light;
  ExposureErrors out;
  out.exposure_min = 1e9;
  while (auto frame = sim.next(light_factor)) {
    const double truth = *frame->frame.exposure_ms * frame->frame.gain.value_or(1.0);
    out.exposure_min = std::min(out.exposure_min, truth);
    out.exposure_max = std::max(out.exposure_max, truth);
    const TrackedFrame& tracked = tracker.process(frame->frame);
    log_light.clear();
    for (const TrackObservation& t : tracked.tracks)
      log_light.push_back(log_illumination(*frame->frame.illuminator_power_w, sim.light_distance(frame->depth, t.position)));
    const ExposureEstimate& e = estimator.update(tracked, light_factor ? &log_light : nullptr);
    EXPECT_TRUE(e.exposure.has_value()) << e.reason;
    if (!e.exposure) continue;
    EXPECT_TRUE(std::isfinite(*e.exposure));
    if (e.status == ExposureStatus::Estimated) ++out.estimated;
    errors.push_back(std::abs(*e.exposure / truth - 1.0));
  }
  if (errors.empty()) return out;
  out.max = *std::max_element(errors.begin(), errors.end());
  std::nth_element(errors.begin(), errors.begin() + static_cast<std::ptrdiff_t>(errors.size() / 2), errors.end());
  out.median = errors[errors.size() / 2];
  return out;
}

SimulatorOptions small_sequence() {
  SimulatorOptions o;
  o.scene = sim::SceneKind::Room;
  o.width = 320;
  o.height = 240;
  o.supersampling = 1;
  o.frames = 80;
  o.exposure_mode = ExposureMode::Auto;
  o.exposure_ms = 2.0;  // far from the auto-exposure target, so the exposure moves
  return o;
}

TEST(ExposureEstimator, ConstantRadianceMedianErrorUnderTwoPercent) {
  SimulatorOptions o = small_sequence();
  o.powers_w = {0.0};
  o.ambient_irradiance = 0.4;  // ambient only: radiance does not depend on the camera's position
  const ExposureErrors errors = run_sequence(o);
  std::printf("ambient only: exposure %.3f..%.3f ms, median error %.4f, max %.4f, %d estimated\n",
              errors.exposure_min, errors.exposure_max, errors.median, errors.max, errors.estimated);
  EXPECT_GT(errors.exposure_max / errors.exposure_min, 1.5) << "the sequence must exercise the exposure";
  EXPECT_GT(errors.estimated, static_cast<int>(o.frames) * 3 / 4);
  EXPECT_LT(errors.median, 0.02);
}

TEST(ExposureEstimator, CoLocatedIlluminatorIsWorseButFinite) {
  SimulatorOptions o = small_sequence();
  o.powers_w = {50.0};
  o.ambient_irradiance = 0.0;
  const ExposureErrors errors = run_sequence(o);
  std::printf("illuminator only: exposure %.3f..%.3f ms, median error %.4f, max %.4f, %d estimated\n",
              errors.exposure_min, errors.exposure_max, errors.median, errors.max, errors.estimated);
  // Reported, not bounded: the lamp moves with the camera, so a patch's radiance grows as the
  // camera approaches it (inverse square) and the constant-radiance estimate absorbs that as
  // exposure (about 100 % median error on this sequence). The back end has to model the lamp.
  EXPECT_TRUE(std::isfinite(errors.median));
  EXPECT_TRUE(std::isfinite(errors.max));
  EXPECT_GT(errors.estimated, static_cast<int>(o.frames) * 3 / 4);
}

// Issue 8, calibration side: the same lamp-lit sequence (texture independent of distance, so the
// lamp is the only reason radiance changes) without and with the (d_ref/d)^2 factor from the true
// distances.
TEST(ExposureEstimator, CoLocatedIlluminatorWithTrueDistances) {
  SimulatorOptions o = small_sequence();
  o.texture_filtering = TextureFiltering::DistanceIndependent;
  o.powers_w = {50.0};
  o.ambient_irradiance = 0.0;
  const ExposureErrors plain = run_sequence(o, false);
  const ExposureErrors lit = run_sequence(o, true);
  std::printf("illuminator only: median error %.4f (max %.4f) without the distance factor, %.4f (max %.4f) with it\n",
              plain.median, plain.max, lit.median, lit.max);
  // Measured: 94 % median error without the factor, 2.15 % (max 3.5 %) with it. The rest is the
  // cos(theta) term a distance alone does not give (illumination_factor.hpp) and the halo
  // factor's polynomial fit; the 2 % is not quite reached here.
  EXPECT_GT(lit.estimated, static_cast<int>(o.frames) * 3 / 4);
  EXPECT_LT(lit.median, 0.03);
  EXPECT_LT(lit.max, 0.06);
  EXPECT_LT(lit.median, 0.05 * plain.median);
}

// The trusted grey range (exposure_estimator.hpp): pixels whose grey value lies outside the range
// the response was fitted over are down-weighted. Frames through a LINEAR response (16-bit grey =
// irradiance), read with the log preset: a 5 % exposure step then looks like a log ratio of about
// 1.4 x log(1.05) on dark patches (grey 0.1-0.28 of full scale) and 2.7 x on bright ones (0.5-0.85),
// since d log G / d log y of the log curve grows with y. The dark third of the image alone is
// trusted: the estimate must follow its tracks, while without a range the bright majority wins.
// The camera approaching a flat surface (a zoom about the image centre by 2.5 % per frame) whose
// tracked features are small dark spots on a brighter ground, with the exposure changing and the
// tracks at the spots' true positions: the fixed 9 x 9 window covers less of the ground and more
// of the spot as the zoom grows, so its irradiance falls against the anchor although the radiance
// of every surface point is constant (the simulated tunnel's exposure drift, exposure_estimator.hpp).
// With follow_deformation the window is warped by the neighbours' zoom and covers the same surface.
TEST(ExposureEstimator, PatchesFollowTheSurfaceAsTheCameraApproaches) {
  constexpr int kWidth = 320, kHeight = 240, kFrames = 20, kSpacing = 16;
  const Eigen::Vector2d centre(0.5 * (kWidth - 1), 0.5 * (kHeight - 1));
  // Spots on a 16 px grid (in surface coordinates = frame 0's pixels), jittered by up to 3 px.
  std::vector<Eigen::Vector2d> spots;
  cv::RNG rng(5);
  const int cols = kWidth / kSpacing + 1, rows = kHeight / kSpacing + 1;
  for (int gy = 0; gy < rows; ++gy)
    for (int gx = 0; gx < cols; ++gx)
      spots.emplace_back(gx * kSpacing + rng.uniform(-3.0, 3.0), gy * kSpacing + rng.uniform(-3.0, 3.0));
  const auto radiance = [&](const Eigen::Vector2d& u) {
    double value = 0.5;
    const int gx = static_cast<int>(std::lround(u.x() / kSpacing)), gy = static_cast<int>(std::lround(u.y() / kSpacing));
    for (int y = std::max(gy - 1, 0); y <= std::min(gy + 1, rows - 1); ++y)
      for (int x = std::max(gx - 1, 0); x <= std::min(gx + 1, cols - 1); ++x)
        value -= 0.3 * std::exp(-0.5 * (u - spots[static_cast<std::size_t>(y * cols + x)]).squaredNorm() / (1.5 * 1.5));
    return value;
  };
  const auto exposure = [](int k) { return 1.0 + 0.2 * std::sin(0.7 * k); };
  const auto final_log_error = [&](bool follow) {
    ExposureEstimatorOptions options;
    options.follow_deformation = follow;
    ExposureEstimator estimator(ResponseModel::from_preset(ResponsePreset::Linear), VignetteModel{}, options);
    TrackDeformation deformation;  // what the tracker runs with estimate_deformation
    ExposureEstimate last;
    for (int k = 0; k < kFrames; ++k) {
      const double zoom = std::pow(1.025, k);
      TrackedFrame tracked;
      tracked.frame_index = k;
      tracked.width = kWidth;
      tracked.height = kHeight;
      tracked.intensity.create(kHeight, kWidth, CV_32FC1);
      for (int y = 0; y < kHeight; ++y)
        for (int x = 0; x < kWidth; ++x)
          tracked.intensity.at<float>(y, x) =
              static_cast<float>(0.6 * exposure(k) * radiance(centre + (Eigen::Vector2d(x, y) - centre) / zoom));
      for (std::size_t j = 0; j < spots.size(); ++j) {
        const Eigen::Vector2d position = centre + zoom * (spots[j] - centre);
        if (position.x() < 12.0 || position.y() < 12.0 || position.x() > kWidth - 13.0 || position.y() > kHeight - 13.0) continue;
        TrackObservation track;
        track.id = static_cast<std::int64_t>(j);
        track.position = position;
        track.age = k;
        track.samples.setZero();  // not read by the estimator (it samples `intensity`)
        track.reference.setZero();
        tracked.tracks.push_back(track);
      }
      if (follow) deformation.update(tracked);
      last = estimator.update(tracked);
      EXPECT_TRUE(last.updated()) << last.reason;
    }
    return std::log(*last.exposure) - std::log(exposure(kFrames - 1) / exposure(0));
  };
  const double fixed = final_log_error(false), following = final_log_error(true);
  std::printf("log exposure error after a %.2fx zoom: fixed window %+.4f, following the surface %+.4f\n",
              std::pow(1.025, kFrames - 1), fixed, following);
  // Measured (this test's printout, `ctest --test-dir build -R PatchesFollowTheSurface`): fixed
  // window -0.158, following the surface -0.0002.
  EXPECT_LT(fixed, -0.10);
  EXPECT_LT(std::abs(following), 0.002);
}

TEST(ExposureEstimator, TrustedGreyRangeFollowsTheTrustedPatches) {
  cv::Mat base = texture(240, 200, 11);
  for (int y = 0; y < base.rows; ++y)
    for (int x = 0; x < base.cols; ++x) {
      float& v = base.at<float>(y, x);
      v = x < base.cols / 3 ? 0.5f * v + 0.05f : v + 0.4f;  // [0.1, 0.275] left, [0.5, 0.85] right
    }
  const ResponseModel log_response = ResponseModel::from_preset(ResponsePreset::Log);
  const auto log_ratio_of = [&](std::optional<std::pair<double, double>> trusted) {
    PhotometricTracker tracker;
    ExposureEstimator estimator(log_response, VignetteModel{});
    estimator.set_model(log_response, VignetteModel{}, trusted);
    estimator.update(tracker.process(make_frame(shifted(base, Eigen::Vector2d::Zero(), 1.0), 16, 0, std::nullopt)));
    const ExposureEstimate& e =
        estimator.update(tracker.process(make_frame(shifted(base, Eigen::Vector2d::Zero(), 1.05), 16, 1, std::nullopt)));
    EXPECT_EQ(e.status, ExposureStatus::Estimated) << e.reason;
    return e.log_exposure_ratio / std::log(1.05);
  };
  const double all = log_ratio_of(std::nullopt);
  const double dark = log_ratio_of(std::make_pair(0.0, 0.3 * 255.0));
  std::printf("log ratio / log 1.05: every grey level trusted %.3f, grey 0..77 trusted %.3f\n", all, dark);
  // The log curve's d log G / d log y is 1.2-1.6 over the dark texture, 2.3-3.0 over the bright.
  EXPECT_GT(all, 2.2);
  EXPECT_GT(dark, 1.1);
  EXPECT_LT(dark, 1.7);
}

class ExposureDegenerate : public ::testing::Test {
protected:
  ExposureDegenerate() : estimator_(ResponseModel::from_preset(ResponsePreset::Gamma), VignetteModel{}) {}
  const ExposureEstimate& feed(const cv::Mat& image, std::int64_t index, std::optional<double> exposure_ms) {
    return estimator_.update(tracker_.process(make_frame(image, 16, index, exposure_ms)));
  }
  PhotometricTracker tracker_;
  ExposureEstimator estimator_;
  cv::Mat base_ = texture(320, 240, 3);
};

TEST_F(ExposureDegenerate, SingleFrameIsTheNormalisation) {
  const ExposureEstimate& e = feed(shifted(base_, Eigen::Vector2d(0.0, 0.0), 1.0), 0, 8.0);
  EXPECT_EQ(e.status, ExposureStatus::FirstFrame);
  ASSERT_TRUE(e.exposure);
  EXPECT_DOUBLE_EQ(*e.exposure, 8.0);
  EXPECT_FALSE(e.reason.empty());
}

TEST_F(ExposureDegenerate, UnreportedExposureStartsAtOne) {
  const ExposureEstimate& e = feed(shifted(base_, Eigen::Vector2d(0.0, 0.0), 1.0), 0, std::nullopt);
  ASSERT_TRUE(e.exposure);
  EXPECT_DOUBLE_EQ(*e.exposure, 1.0);
  // A static camera with a brighter image: the gamma preset's inverse is close to y^2.2.
  const ExposureEstimate& next = feed(shifted(base_, Eigen::Vector2d(0.0, 0.0), 1.6), 1, std::nullopt);
  ASSERT_EQ(next.status, ExposureStatus::Estimated) << next.reason;
  EXPECT_GT(*next.exposure, 2.0);
  EXPECT_TRUE(std::isfinite(next.log_exposure_ratio));
}

TEST_F(ExposureDegenerate, BlackSaturatedAndFlatFramesKeepTheLastEstimate) {
  feed(shifted(base_, Eigen::Vector2d(0.0, 0.0), 1.0), 0, 8.0);
  const double good = *feed(shifted(base_, Eigen::Vector2d(0.5, 0.3), 1.0), 1, 8.0).exposure;
  ASSERT_TRUE(std::isfinite(good));

  const cv::Mat black = cv::Mat::zeros(base_.size(), CV_16U);
  const ExposureEstimate& b = feed(black, 2, std::nullopt);
  EXPECT_EQ(b.status, ExposureStatus::BlackFrame);
  EXPECT_NE(b.reason.find("black"), std::string::npos);
  ASSERT_TRUE(b.exposure);
  EXPECT_DOUBLE_EQ(*b.exposure, good);

  const cv::Mat saturated(base_.size(), CV_16U, cv::Scalar(65535));
  const ExposureEstimate& s = feed(saturated, 3, std::nullopt);
  EXPECT_EQ(s.status, ExposureStatus::SaturatedFrame);
  EXPECT_NE(s.reason.find("saturated"), std::string::npos);
  EXPECT_DOUBLE_EQ(*s.exposure, good);

  // Flat grey: nothing to track.
  const cv::Mat flat(base_.size(), CV_16U, cv::Scalar(20000));
  const ExposureEstimate& f = feed(flat, 4, std::nullopt);
  EXPECT_EQ(f.status, ExposureStatus::TooFewTracks);
  EXPECT_NE(f.reason.find("too few"), std::string::npos);
  EXPECT_DOUBLE_EQ(*f.exposure, good);
  EXPECT_FALSE(std::isnan(f.log_exposure_ratio));

  // Texture again, no reported exposure: the chain restarts at the last estimate and says so.
  const ExposureEstimate& r = feed(shifted(base_, Eigen::Vector2d(0.0, 0.0), 1.0), 5, std::nullopt);
  EXPECT_EQ(r.status, ExposureStatus::Restarted);
  EXPECT_DOUBLE_EQ(*r.exposure, good);
  EXPECT_NE(r.reason.find("restarted"), std::string::npos);
}

// A new model from the back end: every anchor's patch is sampled again under it from the grey
// values it keeps, and the chain goes on, so the next frame's own change of exposure is measured
// (dropping the anchors and restarting at the last estimate took it for none).
TEST_F(ExposureDegenerate, NewModelSamplesTheAnchorsAgain) {
  feed(shifted(base_, Eigen::Vector2d(0.0, 0.0), 1.0), 0, 8.0);
  const double good = *feed(shifted(base_, Eigen::Vector2d(0.4, 0.2), 1.0), 1, std::nullopt).exposure;
  estimator_.set_model(ResponseModel::from_preset(ResponsePreset::Linear), VignetteModel{});
  // Linear response: 1.3x brighter is 1.3x exposure.
  const ExposureEstimate& e = feed(shifted(base_, Eigen::Vector2d(0.8, 0.4), 1.3), 2, std::nullopt);
  ASSERT_EQ(e.status, ExposureStatus::Estimated) << e.reason;
  EXPECT_NE(e.reason.find("changed"), std::string::npos) << e.reason;
  EXPECT_NEAR(*e.exposure / good, 1.3, 0.02);
  const ExposureEstimate& next = feed(shifted(base_, Eigen::Vector2d(1.2, 0.6), 1.3 * 1.3), 3, std::nullopt);
  ASSERT_EQ(next.status, ExposureStatus::Estimated) << next.reason;
  EXPECT_TRUE(next.reason.empty()) << next.reason;
  EXPECT_NEAR(*next.exposure / good, 1.69, 0.04);
}

// The anchors sampled again equal anchors taken afresh under the new model: the same frames fed
// to an estimator that had the new model from the start give the same estimate.
TEST_F(ExposureDegenerate, AnchorsSampledAgainMatchAnchorsTakenUnderTheNewModel) {
  const VignetteModel vignette{Eigen::Vector3d(-0.3, 0.05, -0.02)};
  ExposureEstimator fresh(ResponseModel::from_preset(ResponsePreset::Log), vignette);
  PhotometricTracker fresh_tracker;
  const auto frame = [&](std::int64_t index, double gain, std::optional<double> exposure) {
    return make_frame(shifted(base_, Eigen::Vector2d(0.35 * static_cast<double>(index), 0.2), gain), 16, index, exposure);
  };
  feed(shifted(base_, Eigen::Vector2d(0.0, 0.2), 1.0), 0, 8.0);
  fresh.update(fresh_tracker.process(frame(0, 1.0, 8.0)));
  estimator_.set_model(ResponseModel::from_preset(ResponsePreset::Log), vignette);
  const ExposureEstimate& changed = estimator_.update(tracker_.process(frame(1, 1.2, std::nullopt)));
  const ExposureEstimate& from_start = fresh.update(fresh_tracker.process(frame(1, 1.2, std::nullopt)));
  ASSERT_EQ(changed.status, ExposureStatus::Estimated) << changed.reason;
  ASSERT_EQ(from_start.status, ExposureStatus::Estimated) << from_start.reason;
  EXPECT_NEAR(*changed.exposure, *from_start.exposure, 1e-9 * *from_start.exposure);
  EXPECT_GT(*changed.exposure, 8.0 * 1.2);  // the log curve's inverse is steeper than linear
}

// A new model and a reported exposure: the chain restarts there, as the back end's keyframes
// hold the reported values.
TEST_F(ExposureDegenerate, NewModelWithAReportedExposureRestartsThere) {
  feed(shifted(base_, Eigen::Vector2d(0.0, 0.0), 1.0), 0, 8.0);
  feed(shifted(base_, Eigen::Vector2d(0.4, 0.2), 1.0), 1, std::nullopt);
  estimator_.set_model(ResponseModel::from_preset(ResponsePreset::Linear), VignetteModel{});
  const ExposureEstimate& e = feed(shifted(base_, Eigen::Vector2d(0.8, 0.4), 1.3), 2, 9.0);
  EXPECT_EQ(e.status, ExposureStatus::Restarted);
  EXPECT_NE(e.reason.find("changed"), std::string::npos) << e.reason;
  EXPECT_DOUBLE_EQ(*e.exposure, 9.0);
}

// A first frame so bright that the anchored patches are clipped: the anchored tracks give too
// few ratios while the next frames' patches are fine. The chain restarts on them (here at the
// reported exposure) instead of keeping the first frame's value until the last anchored track dies.
TEST_F(ExposureDegenerate, AnchorsClippedInABrightFirstFrameRestartTheChain) {
  // Texture values are 0.1-0.45 of full scale (about 0.28 +- 0.045): at 3.5x about half of the
  // pixels saturate, under the 90 % that makes a frame say nothing.
  constexpr double kBrightFirstFrameGain = 3.5;
  // A patch needs 70 of its 81 pixels unclipped here, so that a first frame with about half of
  // its pixels saturated leaves (almost) no usable anchor.
  ExposureEstimatorOptions options;
  options.min_valid_pixels = 70;
  ExposureEstimator estimator(ResponseModel::from_preset(ResponsePreset::Gamma), VignetteModel{}, options);
  const auto feed_own = [&](double gain, std::int64_t index, std::optional<double> exposure_ms) -> const ExposureEstimate& {
    return estimator.update(tracker_.process(make_frame(shifted(base_, Eigen::Vector2d(0.3 * static_cast<double>(index), 0.1), gain), 16, index, exposure_ms)));
  };
  const ExposureEstimate& first = feed_own(kBrightFirstFrameGain, 0, 20.0);
  ASSERT_EQ(first.status, ExposureStatus::FirstFrame) << first.reason;
  const ExposureEstimate& restarted = feed_own(1.0, 1, 5.0);
  EXPECT_EQ(restarted.status, ExposureStatus::Restarted) << restarted.reason;
  EXPECT_NE(restarted.reason.find("too few anchored"), std::string::npos) << restarted.reason;
  EXPECT_DOUBLE_EQ(*restarted.exposure, 5.0);
  const ExposureEstimate& next = feed_own(1.2, 2, std::nullopt);
  ASSERT_EQ(next.status, ExposureStatus::Estimated) << next.reason;
  EXPECT_GT(next.used_tracks, 12);
  // The gamma preset's inverse is close to y^2.2: 1.2x brighter is about 1.5x exposure.
  EXPECT_NEAR(*next.exposure / 5.0, std::pow(1.2, 2.2), 0.1);
}

// Under the lamp a track's light factor can be unknown in one frame and known in the next (the
// pipeline's distances come from the odometry's points near it). Here the left half of the
// tracks has a distance in frames 0-1, the right half from frame 2 on and the left half no more:
// a track anchored without a factor would stay unusable for its whole life, and the estimator,
// anchoring only after an estimate, would never get one again.
TEST_F(ExposureDegenerate, TracksWhoseLightFactorComesLaterAreUsedThen) {
  std::vector<double> log_light;
  const auto feed_lit = [&](std::int64_t index, bool left_lit, bool right_lit) -> const ExposureEstimate& {
    const TrackedFrame& tracked = tracker_.process(make_frame(shifted(base_, Eigen::Vector2d(0.0, 0.0), 1.0), 16, index, 8.0));
    log_light.clear();
    for (const TrackObservation& t : tracked.tracks)
      log_light.push_back((t.position.x() < 160.0 ? left_lit : right_lit) ? 0.0 : std::nan(""));
    return estimator_.update(tracked, &log_light);
  };
  EXPECT_EQ(feed_lit(0, true, false).status, ExposureStatus::FirstFrame);
  EXPECT_EQ(feed_lit(1, true, false).status, ExposureStatus::Estimated);
  // The anchored (left) tracks lost their factor: the chain restarts on the right half.
  const ExposureEstimate& restarted = feed_lit(2, false, true);
  EXPECT_EQ(restarted.status, ExposureStatus::Restarted) << restarted.reason;
  const ExposureEstimate& e = feed_lit(3, false, true);
  ASSERT_EQ(e.status, ExposureStatus::Estimated) << e.reason;
  EXPECT_GT(e.used_tracks, 12);
  EXPECT_NEAR(*e.exposure, 8.0, 0.08);  // a static scene: the reported exposure
}

TEST_F(ExposureDegenerate, BlackFirstFrameGivesNoEstimateNotNaN) {
  const ExposureEstimate& e = feed(cv::Mat::zeros(base_.size(), CV_16U), 0, 5.0);
  EXPECT_EQ(e.status, ExposureStatus::BlackFrame);
  EXPECT_FALSE(e.exposure.has_value());
  EXPECT_FALSE(e.updated());
}

}  // namespace
}  // namespace nirslam
