#pragma once

// The monocular initialiser, after DSO's CoarseInitializer: points of the first frame start at
// inverse depth 1; every following frame is aligned coarse-to-fine, jointly refining its pose,
// affine brightness and all inverse depths (Schur complement over the points). While the
// translation is small the depths are pulled to 1 and the translation to 0 (rotation alone
// explains small motions); once the translational flow exceeds the parallax threshold the
// alignment "snaps": depths are regularised towards their neighbours' mean instead, and a few
// frames later the result is handed to the window.

#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nirslam/geometry/se3.hpp"
#include "nirslam/odometry/image_pyramid.hpp"

namespace nirslam::odometry {

struct InitializerOptions {
  int points = 1500;
  double min_gradient = 7.0;
  double huber_threshold = 9.0;
  double min_parallax_px = 6.0;      // rms translational flow at level 0
  int frames_after_snap = 4;
  // Before snapping, depths are held at 1 and the translation at 0 by strong priors (DSO's
  // alphaW = 150^2, per point): over a small baseline a sideways translation with free depths
  // explains a rotation as well as the rotation does, and picking it would distort the map.
  double depth_prior_weight = 150.0 * 150.0;
  double translation_prior_weight = 150.0 * 150.0;  // times the point count
  double neighbour_weight = 1.0;     // after snapping: rho -> median of neighbours (DSO's coupling)
  // From the snap on, four hypotheses are aligned side by side, each from its own last state:
  // the pre-snap pose; the same translation with no rotation; the pre-snap rotation with the
  // translation (same length) along the optical axis, forwards and backwards. The one with the
  // lowest energy on the newest frame (see hypothesis_margin) is the current state and is handed
  // over. Before the snap
  // the translation is held near 0, so under forward motion the rotation absorbs part of the
  // expanding flow (a pitch of a degree or more on the vehicle sequences), and the joint depth +
  // pose alignment started there alone settled on a wrong structure that the window carried on
  // (8-13 % of the path on the vehicle sequences; README, "Odometry benchmark").
  bool multi_start_at_snap = true;
  // Another hypothesis replaces the pre-snap one only with an energy this fraction lower. Tuned
  // on the bench sequences (energies on the last initialiser frame): the forward start wins by
  // 29-41 % on the vehicle sequences, where the pre-snap one gives 8-13 % of the path; other
  // starts win by 17-23 % in the room and tunnel at 50 W, where the pre-snap one is the better
  // start (room 50 W: 0.7 % of the path against 2.2 %).
  double hypothesis_margin = 0.25;
  // The hypotheses are independent: they are aligned on two threads (the caller's and one
  // more), each on its own copy of the initialiser; the result is the same as one after the
  // other (false), about twice as fast on an idle two-core machine.
  bool parallel_hypotheses = true;
  double affine_a_prior = 1.0;
  double affine_b_prior = 1e-2;
};

enum class InitializerState { NeedFirstFrame, Tracking, Succeeded, Failed };

// Wall time of the initialiser's phases since its first frame (README, "Speed").
struct InitializerTimings {
  double pre_snap_s = 0.0;  // the alignment before the snap
  double align_s = 0.0;     // the hypotheses' frame-by-frame alignment after it
};

struct InitialPoint {
  Eigen::Vector2d pixel;
  double inverse_depth = 1.0;
  bool good = true;  // inlier in the last frame
};

class CoarseInitializer {
public:
  CoarseInitializer(std::vector<LevelCamera> cameras, const InitializerOptions& options);

  void set_first(std::shared_ptr<const ImagePyramid> pyramid, double exposure);
  // Aligns one more frame; Succeeded once enough parallax was kept for frames_after_snap frames.
  InitializerState add_frame(std::shared_ptr<const ImagePyramid> frame, double exposure);
  // Poses from a geometric start (geometric_start.hpp) of the frames this initialiser will be
  // given, by add_frame's count (index 0: the first frame). After the snap a single hypothesis is
  // aligned, each frame started from that frame's pose and its camera centre held to the pose's
  // direction from the first frame (the length free); the multi-start is skipped.
  // Frames after the last pose keep the last direction held; a snap after it ignores the poses.
  void set_geometric_poses(std::vector<SE3> T_frame_first) { geometric_ = std::move(T_frame_first); }
  // A frame after the snap was aligned from a geometric pose (its direction held).
  bool aligned_to_geometric_poses() const { return aligned_to_geometric_; }
  // Ends early with the current estimate (a static camera): depths stay near 1.
  void force_success() { state_ = InitializerState::Succeeded; }

  InitializerState state() const { return state_; }
  bool snapped() const { return snapped_; }
  int frames_tracked() const { return frames_; }
  const SE3& T_frame_first() const { return T_frame_first_; }  // last frame
  double affine_a() const { return a_; }
  double affine_b() const { return b_; }
  double rms() const { return rms_; }
  double parallax_px() const { return parallax_; }
  double inlier_fraction() const;  // of the points, in the last frame
  const std::vector<InitialPoint>& points() const { return points_; }
  const std::shared_ptr<const ImagePyramid>& first_pyramid() const { return first_; }
  double first_exposure() const { return first_exposure_; }
  const InitializerTimings& timings() const { return timings_; }
  // Hypotheses aligned on the last frame (the starts).
  std::size_t hypothesis_count() const { return hypotheses_.size(); }

private:
  // One LM iteration set on a level; returns the rms.
  double optimize_level(int level, const ImagePyramid& frame, double exposure, int iterations);
  double evaluate(int level, const ImagePyramid& frame, double exposure, const SE3& T, double a, double b,
                  const std::vector<double>& rho, bool linearize);
  void update_neighbour_means();
  // Coarse-to-fine alignment of `frame` from the current state, every level.
  void optimize_levels(const ImagePyramid& frame, double exposure);
  // Mean inverse depth 1 (the translation scales along); returns the factor the translation got.
  double normalise_gauge();
  // Rms pixel shift at level 0 caused by the translation alone, for a 640-wide image.
  double translational_parallax() const;
  // After the snap: every hypothesis aligned to `frame` from its own last state; the pre-snap
  // one stays the current state unless another is hypothesis_margin lower in energy (level 0,
  // regulariser included).
  void align_hypotheses(const ImagePyramid& frame, double exposure);
  // Index of that choice among the starts.
  std::size_t best_hypothesis() const;
  // Aligns hypotheses [begin, end) one after the other on `worker` (a copy of this initialiser,
  // or this one): each from its own state, so the order does not matter.
  void align_hypothesis_range(CoarseInitializer& worker, std::size_t begin, std::size_t end, const ImagePyramid& frame,
                              double exposure);
  struct Hypothesis {
    SE3 T;
    double a = 0.0, b = 0.0;
    std::vector<InitialPoint> points;
    double energy = 0.0;
    // The camera centre's direction (first frame) held while it is aligned (a geometric
    // start's pose); zero: free.
    Eigen::Vector3d hold_direction = Eigen::Vector3d::Zero();
  };
  Hypothesis current_state() const { return {T_frame_first_, a_, b_, points_, 0.0, Eigen::Vector3d::Zero()}; }
  // Runs `range(worker, b, e)` over the hypotheses, on two threads when allowed.
  template <class Range>
  void for_hypotheses(Range range);
  void load(const Hypothesis& h);

  std::vector<LevelCamera> cameras_;
  InitializerOptions options_;
  std::shared_ptr<const ImagePyramid> first_;
  double first_exposure_ = 1.0;
  std::vector<InitialPoint> points_;
  std::vector<std::array<int, 6>> neighbours_;
  std::vector<double> neighbour_mean_;
  InitializerState state_ = InitializerState::NeedFirstFrame;
  SE3 T_frame_first_;
  double a_ = 0.0;
  double b_ = 0.0;
  bool snapped_ = false;
  int frames_ = 0;
  int frames_since_snap_ = 0;
  double rms_ = 0.0;
  double parallax_ = 0.0;
  std::vector<SE3> geometric_;          // set_geometric_poses
  bool aligned_to_geometric_ = false;
  std::vector<Hypothesis> hypotheses_;  // after the snap
  Eigen::Vector3d hold_direction_ = Eigen::Vector3d::Zero();  // of the hypothesis being aligned
  InitializerTimings timings_;

  // Scratch of evaluate(..., linearize = true).
  Eigen::Matrix<double, 8, 8> H_ff_;
  Eigen::Matrix<double, 8, 1> b_f_;
  std::vector<Eigen::Matrix<double, 8, 1>> H_fp_;
  std::vector<double> H_pp_;
  std::vector<double> b_p_;
  std::vector<int> inliers_;
};

}  // namespace nirslam::odometry
