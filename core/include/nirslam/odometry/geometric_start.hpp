#pragma once

// The translation direction for the direct initialiser from feature geometry (issue 7). Over the
// first frames of a hand-held start, the direct energy leaves the camera's translation direction
// 10-70 degrees off (the co-located lamp brightens each patch by its own factor, and a vertical
// translation and a pitch make nearly the same flow towards walls of similar depth); held at the
// true direction, the 12-run start set of the room and tunnel goes from 2.1 % of the path to
// 0.75 % (README, "Odometry benchmark"). Corners of the first frame are followed by the
// gain-robust KLT of the photometric front end (tracks survive the auto exposure's steps) over
// `frames` frames; the essential matrix between the first and the last frame (five-point RANSAC)
// gives a start, PnP the frames between, and a bundle adjustment of all frames' poses and the
// points (Levenberg-Marquardt with the Schur complement over the points, Huber weights) the
// result. Two views alone were 1-19 degrees off in the rooms (session 16); a throwaway version
// of this over 20 frames was within 2.3 degrees on every start of the set, nirslam's within
// 1.3-2.5 on the one start measured (room 100 W from frame 0, README "Odometry benchmark").

#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "nirslam/geometry/se3.hpp"
#include "nirslam/odometry/image_pyramid.hpp"

namespace nirslam::odometry {

struct GeometricStartOptions {
  int frames = 20;                    // after the first: the last frame's index
  int max_corners = 800;
  double corner_quality = 0.003;      // of the strongest corner
  double min_corner_distance_px = 8.0;
  // The gain-robust KLT's checks, looser than the photometric front end's (0.04, 0.5 px): on the
  // room at 100 W from its first frame (the auto exposure ramping down) the front end's 0.04
  // left 68 tracks to the 20th frame and the direction 6-10 degrees off; 0.08 and 0.5 px, 79
  // tracks and 1.3-2.5 degrees (test GeometricStart.DirectionOfTheHandHeldRoomUnderTheLamp).
  double max_track_residual = 0.08;   // rms after the brightness fit, fraction of full scale
  double max_forward_backward_px = 0.5;
  int min_track_frames = 4;           // a track shorter than this is not triangulated
  int min_inliers = 50;               // essential-matrix inliers among the tracks reaching the end
  double ransac_threshold_px = 1.0;
  double huber_px = 1.0;
  double max_rms_px = 1.5;            // after the bundle adjustment
  // The flow the translation adds to the rotation's in the last frame (rms over the points that
  // reach it): under a rotation alone the direction is undetermined. The direct initialiser
  // snaps at 6 px. A second guard: small baselines are refused first by the inlier count, since
  // the essential matrix's pose recovery drops points beyond 50 baselines (1-5 cm between walls
  // at 2 and 4 m: 0-23 inliers; test GeometricStart.TooLittleTranslationLeavesTheDirectionUndetermined).
  double min_parallax_px = 4.0;
  int iterations = 30;
};

struct BundleObservation {
  int frame = 0;  // 0 = the first frame (held fixed)
  int point = 0;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
};

// The reprojection residual pi(T X) - pixel and its Jacobians in a left perturbation of T
// (exp(xi) T, xi = (upsilon, omega)) and in X. false when the point is not in front of the camera.
bool reprojection_jacobians(const LevelCamera& cam, const SE3& T_frame_first, const Eigen::Vector3d& point_first,
                            const Eigen::Vector2d& pixel, Eigen::Vector2d& residual,
                            Eigen::Matrix<double, 2, 6>& d_pose, Eigen::Matrix<double, 2, 3>& d_point);

struct BundleResult {
  double rms_px = 0.0;        // of the inliers (|r| under 3 Huber thresholds)
  int inlier_observations = 0;
  int iterations = 0;
};

// Levenberg-Marquardt over the poses of frames 1.. (frame 0 is the identity and fixed) and the
// points (first-frame coordinates), Huber weights; the scale gauge is left to the damping and
// fixed afterwards by the caller.
BundleResult adjust_bundle(const LevelCamera& cam, std::vector<SE3>& T_frame_first, std::vector<Eigen::Vector3d>& points,
                           const std::vector<BundleObservation>& observations, double huber_px, int iterations);

struct GeometricStartResult {
  bool ok = false;
  std::string reason;  // why not, or a one-line summary
  // Index 0..frames: the frame's pose relative to the first frame, scaled so that the points'
  // mean inverse depth in the first frame is 1 (the direct initialiser's gauge).
  std::vector<SE3> T_frame_first;
  int tracks_at_end = 0;
  int inliers = 0;
  int points = 0;
  double rms_px = 0.0;
  double parallax_px = 0.0;
};

class GeometricStart {
public:
  GeometricStart(const LevelCamera& camera, const GeometricStartOptions& options);

  // `image`: CV_32FC1, 0..255 (as OdometryFrame). Detects the corners.
  void set_first(const cv::Mat& image);
  // Follows the tracks into the next frame.
  void add_frame(const cv::Mat& image);
  // Frames added since the first.
  int frames() const { return static_cast<int>(positions_.size()) - 1; }
  bool complete() const { return frames() >= options_.frames; }
  GeometricStartResult solve() const;

private:
  LevelCamera camera_;
  GeometricStartOptions options_;
  std::vector<cv::Mat> previous_pyramid_;
  // positions_[frame][track]; alive_[frame][track]: followed into that frame.
  std::vector<std::vector<Eigen::Vector2d>> positions_;
  std::vector<std::vector<char>> alive_;
};

}  // namespace nirslam::odometry
