#pragma once

// The real-time front end of the online photometric calibration (issue 6, after Bergmann, Wang and
// Cremers, "Online photometric calibration of auto exposure video"): a gain-robust pyramidal KLT
// that follows small patches from frame to frame while the exposure changes.
//
// Each patch is tracked with a translation d and an affine brightness change (a, b):
//
//   minimise  sum_x ( I_t(x0 + x + d) - a * I_{t-1}(x0 + x) - b )^2   over (d, a, b)
//
// by Gauss-Newton at every pyramid level, coarse to fine. a absorbs the exposure (and gain) ratio
// and b the offset that a non-linear response gives a patch, so tracks survive auto exposure
// steps that break the brightness-constancy assumption of plain KLT. A forward-backward check
// (track t-1 -> t, then back) rejects tracks that do not return to where they started.
//
// Intensities are fractions of full scale (grey / max_value) so 8- and 16-bit frames share the
// thresholds. The per-frame observation of a track is its patch sampled bilinearly at the tracked
// position (grey values, for a back end that fits f and V); the exposure estimator samples the
// frame's `intensity` itself, applying G = f^-1 before interpolating (see exposure_estimator.hpp).

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "nirslam/common/helper_thread.hpp"
#include "nirslam/image/frame.hpp"
#include "nirslam/photometric/track_deformation.hpp"

namespace nirslam {

inline constexpr int kPatchRadius = 4;                        // 9 x 9 patches
inline constexpr int kPatchSide = 2 * kPatchRadius + 1;
inline constexpr int kPatchPixels = kPatchSide * kPatchSide;
// Row-major: sample (i, j) is at position + (j - kPatchRadius, i - kPatchRadius).
using PatchSamples = Eigen::Matrix<float, kPatchPixels, 1>;

struct PhotometricTrackerOptions {
  int pyramid_levels = 3;                  // including full resolution
  int max_iterations = 12;                 // Gauss-Newton steps per level
  double convergence_px = 0.01;            // stop when the step is shorter (at that level)
  int max_tracks = 200;
  int min_tracks = 120;                    // detect new corners when fewer tracks survive
  int grid_cols = 8;                       // detection buckets, so tracks cover the image
  int grid_rows = 6;
  double corner_quality = 0.01;            // relative to the strongest corner (gain invariant)
  double min_corner_distance_px = 10.0;
  // A detected corner is kept only when its patch's gradient tensor has a ratio of smaller to
  // larger eigenvalue of at least this at every pyramid level the tracker uses (corner_isotropy).
  // Shi-Tomasi at a quality relative to the strongest corner keeps stripe ends and corners with a
  // line through them, whose coarse levels (a 9 x 9 patch there spans 36 x 36 px) see one
  // direction only; followed from the simulator's truth, fresh corners below 0.05 came within
  // 0.5 px 13-27 % of the time, at 0.3 and above 58-71 % (README "Illuminator correction",
  // session 36, TrackerAgainstTruth). 0 keeps every corner.
  double min_corner_isotropy = 0.0;
  double max_forward_backward_px = 0.5;
  double max_residual_rms = 0.04;          // after the brightness fit, fraction of full scale
  // Smaller eigenvalue of the patch's mean gradient tensor over its squared mean brightness (so
  // the test does not depend on exposure): 1e-4 = gradients of about 1 % of the brightness per px.
  double min_structure = 1.0e-4;
  // Drift check against the track's FIRST patch: the normalised cross-correlation (invariant to
  // an affine brightness change) of the current patch with the patch at detection must stay at or
  // above this, else the track is dropped. Frame-to-frame KLT lets a patch slide along an edge or
  // follow an occlusion corner (foreground edge over a background that moves with parallax) while
  // every step passes the forward-backward test; the back end, which takes a track's pixels for
  // fixed surface points, then sees their radiance change with the image position (measured in
  // test_photometric_diagnostics.cpp). 0 switches the check off.
  double min_reference_ncc = 0.0;
  double min_brightness_gain = 0.2;        // a outside these: not the same patch
  double max_brightness_gain = 5.0;
  // Near the image border a coarse pyramid level has no room for the patch (level 2 needs
  // 4 (kPatchRadius + 1) = 20 px at full resolution), which ended every track there: at 320 x 240
  // no track got beyond r = 0.85 of the half-diagonal, so the vignette's rim was extrapolated.
  // On: such levels are skipped and the track is refined from the finer levels only (inter-frame
  // motion near the border is what the finer levels can still catch; the forward-backward and
  // residual tests reject the rest). The pipeline's illuminated mode takes
  // PipelineOptions::lamp_mode_track_near_border instead.
  bool skip_coarse_levels_at_border = false;
  // One brightness gain for the whole frame pair (the ratio of the two images' means), held fixed
  // while each patch fits its translation alone, as the gain-robust KLT of Kim et al. does; off:
  // each patch fits its own gain and bias. On a patch that is mostly a brightness ramp a shift and
  // a bias change look alike, so the per-patch fit slides along the ramp: against the simulator's
  // truth, fresh street corners followed within 1 px 45 % per patch, 63 % with the pair's gain.
  // Off by default: under the co-located lamp a patch's brightness ratio depends on its distance,
  // and the pipeline's co-lit rows lost as many tracks to the residual test as they saved (README
  // "Illuminator correction", session 35); without the lamp it is no better, since through a
  // curved response and the vignette an exposure change does not scale every grey value alike
  // (issue 6's table over three draws: vignette rows met 14 -> 9, session 36).
  bool frame_pair_gain = false;
  // After each frame-to-frame step, align the track's FIRST patch to the frame under an affine
  // warp (I(c + W o) = a T(o) + b over the patch offsets o; Gauss-Newton from the step's position
  // and the last frame's W), and take c as the position and W as the track's deformation
  // (TrackedFrame::deformation_estimated; the neighbours' estimate is then not run). A
  // translation-only patch in frame-to-frame steps lands 1-2 px off its surface point as the
  // image magnifies (the simulated tunnel under the lamp: PhotometricAccuracy.
  // DiagnoseLampObservations), and the calibration takes the samples there for that point.
  // Where the first patch does not align within max_reference_shift_px of the step, within
  // max_residual_rms, or with det W outside [1 / max_area_change, max_area_change], the track
  // goes on from the step's position as a new surface (TrackObservation::surface + 1), its patch
  // there the new first patch.
  bool align_reference_affine = false;
  double max_reference_shift_px = 2.0;
  double max_area_change = 4.0;
  double black_level = 0.03;               // for the frame's black / saturated fractions
  double saturation_level = 0.97;
  // Each track's deformation since birth from its neighbours (track_deformation.hpp), for
  // observations that follow the surface (ExposureEstimatorOptions::follow_deformation,
  // OnlineCalibrationOptions::keyframes_follow_deformation set it). Off: every A is I.
  bool estimate_deformation = false;
  TrackDeformationOptions deformation;
};

// One patch tracked between two images.
struct PatchTrack {
  Eigen::Vector2d position = Eigen::Vector2d::Zero();  // in the second image, pixels
  double brightness_gain = 1.0;                         // a: I_t ~ a I_{t-1} + b
  double brightness_bias = 0.0;                         // b, fraction of full scale
  double residual_rms = 0.0;                            // at full resolution
};

// Pyramid of a grey image as CV_32FC1 in fractions of full scale, level 0 = full resolution.
std::vector<cv::Mat> build_intensity_pyramid(const cv::Mat& image, int bit_depth, int levels);

// Tracks the patch at `from` in pyramid `a` into pyramid `b`, starting the search at `guess`.
// std::nullopt when the patch leaves the image, is too flat to track, or does not converge to a
// plausible brightness change. With `pair_gain` the brightness gain is held at it (no bias) and
// only the translation is fitted (PhotometricTrackerOptions::frame_pair_gain). Allocation free.
std::optional<PatchTrack> track_patch(const std::vector<cv::Mat>& a, const std::vector<cv::Mat>& b,
                                      const Eigen::Vector2d& from, const Eigen::Vector2d& guess,
                                      const PhotometricTrackerOptions& options,
                                      std::optional<double> pair_gain = std::nullopt);

// The brightness gain from pyramid `a` to pyramid `b`: the ratio of their coarsest levels' means
// (1 when either is black: no ratio to hold).
double frame_pair_gain(const std::vector<cv::Mat>& a, const std::vector<cv::Mat>& b);

// The smallest, over the pyramid's levels, ratio of smaller to larger eigenvalue of the gradient
// tensor of the patch at `position` (full-resolution pixels): 1 for a blob or an isotropic
// corner, 0 for a straight edge or a flat patch, at any level. Levels the patch does not fit
// (near the border) are left out; 0 when it does not fit the full resolution.
double corner_isotropy(const std::vector<cv::Mat>& pyramid, const Eigen::Vector2d& position);

// Bilinear sample of a CV_32FC1 image; the caller guarantees 0 <= x < cols - 1, 0 <= y < rows - 1.
// Inline: it runs per pixel in the tracker's patch loops.
inline float bilinear_sample(const cv::Mat& image, double x, double y) {
  const int x0 = static_cast<int>(x);
  const int y0 = static_cast<int>(y);
  const float fx = static_cast<float>(x - x0);
  const float fy = static_cast<float>(y - y0);
  const float* row0 = image.ptr<float>(y0) + x0;
  const float* row1 = image.ptr<float>(y0 + 1) + x0;
  return (1.0f - fy) * ((1.0f - fx) * row0[0] + fx * row0[1]) + fy * ((1.0f - fx) * row1[0] + fx * row1[1]);
}

// Samples the patch centred at `position` (bilinear). false when it does not fit in the image.
bool sample_patch(const cv::Mat& image, const Eigen::Vector2d& position, PatchSamples& samples);

// A patch `reference` (kPatchSide x kPatchSide samples, row-major) aligned to `image` (CV_32FC1)
// under an affine warp and brightness change: I(position + warp o) = gain T(o) + bias over the
// patch offsets o, by Gauss-Newton from the given values. std::nullopt when the warped patch
// leaves the image, a step is not finite or the brightness gain goes out of
// [min_brightness_gain, max_brightness_gain].
struct AffinePatchAlignment {
  Eigen::Vector2d position = Eigen::Vector2d::Zero();
  Eigen::Matrix2d warp = Eigen::Matrix2d::Identity();
  double gain = 1.0;
  double bias = 0.0;
  double residual_rms = 0.0;  // fraction of full scale
};
std::optional<AffinePatchAlignment> align_patch_affine(const cv::Mat& image, const PatchSamples& reference,
                                                       const Eigen::Vector2d& position, const Eigen::Matrix2d& warp,
                                                       const PhotometricTrackerOptions& options);

struct TrackObservation {
  std::int64_t id = 0;
  Eigen::Vector2d position = Eigen::Vector2d::Zero();
  int age = 0;                     // frames since detection; 0 = detected in this frame
  PatchSamples samples;            // fraction of full scale, at `position`
  double brightness_gain = 1.0;    // from the previous frame (1 for new tracks)
  PatchSamples reference;          // the patch when the track was detected (drift check)
  // With TrackedFrame::deformation_estimated (track_deformation.hpp): the 2 x 2 map A the image
  // has undergone around the track since its `surface` began (a pixel offset o then is A o now);
  // a track's observations of different surfaces are not of the same surface points.
  Eigen::Matrix2d deformation = Eigen::Matrix2d::Identity();
  std::int32_t surface = 0;
  // With align_reference_affine: the warp W of the first patch into this frame (I at detection).
  Eigen::Matrix2d reference_warp = Eigen::Matrix2d::Identity();
};

// Why the previous frame's tracks that were not followed into a frame ended, by the first check
// each failed.
struct TrackEnds {
  int not_found = 0;         // the patch search failed (left the image, flat patch, gain out of bounds)
  int residual = 0;          // found, but the brightness-fitted residual exceeds max_residual_rms
  int forward_backward = 0;  // tracked back, it did not return within max_forward_backward_px
  int reference = 0;         // too near the border to sample, or no longer like its first look (min_reference_ncc)
  int total() const { return not_found + residual + forward_backward + reference; }
  TrackEnds& operator+=(const TrackEnds& other) {
    not_found += other.not_found;
    residual += other.residual;
    forward_backward += other.forward_backward;
    reference += other.reference;
    return *this;
  }
};

struct TrackedFrame {
  std::int64_t frame_index = 0;
  int width = 0;
  int height = 0;
  std::optional<double> exposure_ms;  // as the source reported them
  std::optional<double> gain;
  double black_fraction = 0.0;        // pixels at or below black_level
  double saturated_fraction = 0.0;    // pixels at or above saturation_level
  std::vector<TrackObservation> tracks;
  // The frame at full resolution, CV_32FC1 in fractions of full scale (shares the tracker's
  // buffer): the exposure estimator samples it after applying G, see exposure_estimator.hpp.
  cv::Mat intensity;
  TrackEnds ended;                    // of the previous frame's tracks
  int new_tracks = 0;
  bool deformation_estimated = false; // the tracks' deformation and surface are set
};

class PhotometricTracker {
public:
  explicit PhotometricTracker(PhotometricTrackerOptions options = {});

  // Tracks the previous frame's patches into `frame` and tops them up with new corners, only
  // where `detection_allowed` (CV_8UC1, the frame's size, nonzero where a corner may be taken)
  // says so when it is given: a caller that knows where patches cannot be followed (a depth edge,
  // from the odometry or a simulator's truth) keeps the track budget for the rest. Throws
  // std::invalid_argument for a malformed frame or mask.
  const TrackedFrame& process(const Frame& frame, const cv::Mat& detection_allowed = cv::Mat());
  const TrackedFrame& last() const { return current_; }
  const PhotometricTrackerOptions& options() const { return options_; }
  void reset();

private:
  void detect(const std::vector<cv::Mat>& pyramid, const cv::Mat& allowed);

  PhotometricTrackerOptions options_;
  std::vector<cv::Mat> previous_pyramid_;
  TrackedFrame current_;
  std::int64_t next_id_ = 0;
  cv::Mat detection_mask_;
  std::vector<int> bucket_counts_;
  // The tracks are followed on two threads (each track alone, so the result is the same);
  // copies share the helper, which serves one caller at a time.
  std::vector<std::optional<TrackObservation>> followed_;
  std::vector<int TrackEnds::*> ends_;  // the counter of the check each track that was not followed failed
  TrackDeformation deformation_;
  std::shared_ptr<HelperThread> helper_ = std::make_shared<HelperThread>();
};

}  // namespace nirslam
