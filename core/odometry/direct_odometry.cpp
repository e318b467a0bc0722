#include "nirslam/odometry/direct_odometry.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <stdexcept>

#include "nirslam/odometry/coarse_initializer.hpp"
#include "nirslam/odometry/coarse_tracker.hpp"
#include "nirslam/odometry/geometric_start.hpp"
#include "nirslam/common/elapsed.hpp"
#include "nirslam/common/helper_thread.hpp"
#include "nirslam/odometry/image_pyramid.hpp"
#include "nirslam/odometry/immature_point.hpp"
#include "nirslam/odometry/pixel_selector.hpp"
#include "nirslam/odometry/surface_normals.hpp"
#include "nirslam/odometry/window_optimizer.hpp"

namespace nirslam {

using namespace odometry;

const char* to_string(TrackingStatus status) {
  switch (status) {
    case TrackingStatus::Initialising: return "initialising";
    case TrackingStatus::Tracking: return "tracking";
    case TrackingStatus::Lost: return "lost";
    case TrackingStatus::NewSegment: return "new segment";
  }
  return "unknown";
}

namespace {

using Clock = std::chrono::steady_clock;

constexpr double kPosePriorWeight = 1e10;
constexpr double kInitialPointPriorWeight = 10.0;

}  // namespace

// The records are Impl's own types, not file-local ones: a class with external linkage may hold
// members of anonymous-namespace types only in the main file of a translation unit
// (-Wsubobject-linkage), and in a unity build this file is not the main one.
struct DirectOdometry::Impl {
  // A keyframe's public state plus the window's id for it, shared by the frames it anchors.
  struct KeyframeRecord : KeyframeState {
    std::int64_t id = 0;
  };

  struct FrameRecord {
    std::int64_t frame_index = 0;
    double timestamp_s = 0.0;
    int segment = 0;
    std::shared_ptr<KeyframeRecord> keyframe;
    SE3 T_kf_frame;
  };

  Impl(const PinholeCamera& camera, const OdometryOptions& o) : options(o) {
    LevelCamera base{camera.fx(), camera.fy(), camera.cx(), camera.cy(), camera.width(), camera.height()};
    levels = usable_levels(camera.width(), camera.height(), o.pyramid_levels, o.min_coarsest_width);
    cameras = make_level_cameras(base, levels);
    image_scale = (camera.width() + camera.height()) / (640.0 + 480.0);
    start_segment(SE3());
    segment = 0;
  }

  // --- state ---
  OdometryOptions options;
  std::vector<LevelCamera> cameras;
  int levels = 1;
  double image_scale = 1.0;

  enum class Phase { Initialising, Tracking };
  Phase phase = Phase::Initialising;
  int segment = 0;
  bool new_segment_pending = false;  // the next initialised pose starts a new segment
  SE3 segment_origin;                // T_world_first of the segment being initialised

  std::unique_ptr<CoarseInitializer> initializer;
  std::int64_t init_first_index = 0;
  double init_first_timestamp = 0.0;
  std::vector<FrameRecord> init_frames;  // T_kf_frame relative to the first frame, pending
  std::vector<SE3> init_T_frame_first;
  // The geometric start of the segment (OdometryOptions::init_geometric_frames) and the frames
  // held back for it; pending until it has its frames.
  std::unique_ptr<GeometricStart> geometric;
  std::vector<OdometryFrame> geometric_frames;
  bool geometric_pending = false;
  // Its poses of the held frames (T_frame_first in its own gauge) and, from a held hand-over on
  // (OdometryOptions::init_hold_geometric_pose), the odometry's translation per geometric unit:
  // keyframes made of held frames are held at those poses (0: none held).
  std::vector<SE3> geometric_poses;
  std::int64_t geometric_first_index = -1;
  double geometric_scale = 0.0;

  std::unique_ptr<WindowOptimizer> window;
  std::unique_ptr<CoarseTracker> tracker;
  std::map<std::int64_t, std::vector<ImmaturePoint>> immature;  // by keyframe id
  std::map<std::int64_t, std::shared_ptr<KeyframeRecord>> window_records;
  std::int64_t next_keyframe_id = 0;
  std::int64_t reference_id = -1;
  double reference_first_rms = -1.0;
  int frames_since_keyframe = 0;
  std::vector<double> last_level_rms;

  // Motion model: the last two frames' T_cam_world.
  std::optional<SE3> last_T_cam_world;
  std::optional<SE3> previous_T_cam_world;
  double last_a = 0.0;
  double last_b = 0.0;

  std::vector<std::shared_ptr<KeyframeRecord>> keyframes;
  std::vector<FrameRecord> frames;
  std::vector<MapPoint> archived_points;

  // The frames carry exposures and no lamp the odometry does not model is on: strong affine priors.
  bool exposure_explains_brightness = false;
  // The lamp's factor in the residuals: options.illuminator_correction while the frames trust it
  // (OdometryFrame::lamp_factor_trusted).
  bool lamp_factor_on = options.illuminator_correction;

  // The second thread of the epipolar searches.
  HelperThread helper;

  // --- helpers ---
  void start_segment(const SE3& origin) {
    geometric_scale = 0.0;
    phase = Phase::Initialising;
    segment_origin = origin;
    InitializerOptions io;
    io.points = options.points_per_frame;
    io.min_gradient = options.min_gradient;
    io.huber_threshold = options.huber_threshold;
    io.min_parallax_px = options.init_min_parallax_px;
    io.affine_a_prior = 0.1 * a_prior(false);
    io.affine_b_prior = 0.1 * b_prior(false);
    initializer = std::make_unique<CoarseInitializer>(cameras, io);
    geometric_frames.clear();
    geometric_pending = options.init_geometric_frames > 0;
    if (geometric_pending) {
      GeometricStartOptions go;
      go.frames = options.init_geometric_frames;
      geometric = std::make_unique<GeometricStart>(cameras[0], go);
    }
    init_frames.clear();
    init_T_frame_first.clear();
    WindowOptions wo;
    wo.huber_threshold = options.huber_threshold;
    wo.gradient_weight_c = options.gradient_weight_c;
    wo.outlier_energy = options.outlier_energy;
    wo.lamp = window_lamp();
    window = std::make_unique<WindowOptimizer>(cameras[0], wo);
    CoarseTrackerOptions to;
    to.huber_threshold = options.huber_threshold;
    to.gradient_weight_c = options.gradient_weight_c;
    to.iterations_per_level = options.tracking_iterations_per_level;
    to.lamp = lamp();
    tracker = std::make_unique<CoarseTracker>(cameras, to);
    tracker->set_affine_priors(0.1 * a_prior(false), 0.1 * b_prior(false));
    immature.clear();
    window_records.clear();
    reference_id = -1;
    reference_first_rms = -1.0;
    frames_since_keyframe = 0;
    last_T_cam_world.reset();
    previous_T_cam_world.reset();
    last_a = 0.0;
    last_b = 0.0;
  }

  odometry::LampGeometry lamp() const {
    return {lamp_factor_on, options.light_offset, options.beam_exponent, options.brightness_exponent,
            options.lamp_factor_derivatives, options.beam_corrected_weights};
  }
  odometry::LampGeometry window_lamp() const {
    odometry::LampGeometry window_geometry = lamp();
    window_geometry.derivatives = window_geometry.derivatives && options.lamp_factor_derivatives_in_window;
    return window_geometry;
  }

  double a_prior(bool first) const {
    if (first) return 1e10;
    return exposure_explains_brightness ? options.affine_a_prior_known_exposure : options.affine_a_prior_free;
  }
  double b_prior(bool first) const {
    if (first) return 1e8;
    return exposure_explains_brightness ? options.affine_b_prior_known_exposure : options.affine_b_prior_free;
  }

  static MapPoint to_map_point(const WindowFrame& host, const WindowPoint& p, const LevelCamera& camera, int seg,
                               bool active) {
    MapPoint m;
    const Eigen::Vector3d p_cam = camera.unproject(p.pixel) / std::max(p.inverse_depth, 1e-6);
    m.p_world = host.state.T_cam_world.inverse() * p_cam;
    m.intensity = p.host_intensity[4];
    m.segment = seg;
    m.active = active;
    return m;
  }

  void sync_records() {
    for (const auto& f : window->frames()) {
      auto& r = window_records[f.id];
      r->T_world_cam = f.state.T_cam_world.inverse();
      r->affine_a = f.state.affine_a;
      r->affine_b = f.state.affine_b;
    }
  }

  void archive_window_points() {
    for (const auto& f : window->frames())
      for (const auto& p : f.points) archived_points.push_back(to_map_point(f, p, cameras[0], segment, false));
  }

  // Normals for the lamp's cos(theta), from the current depths; held fixed while the window is
  // optimised (their dependence on the neighbours' depths is left out of the Jacobians).
  void update_surface_normals() {
    if (!options.illuminator_correction || !options.lamp_surface_normals) return;
    SurfaceNormalOptions normal_options;
    normal_options.fit = options.lamp_surface_normal_fit;
    for (auto& f : window->frames()) estimate_surface_normals(cameras[0], f.points, normal_options);
  }

  // Points of the window in the newest keyframe, for the tracker.
  void update_tracker_reference() {
    const auto& frames_ = window->frames();
    const WindowFrame& ref = frames_.back();
    std::vector<ReferencePoint> points;
    for (const auto& host : frames_) {
      const SE3 T_ref_host = ref.state.T_cam_world * host.state.T_cam_world.inverse();
      const Eigen::Matrix3d R = T_ref_host.rotation_matrix();
      const Eigen::Vector3d t = T_ref_host.translation();
      for (const auto& p : host.points) {
        Warp w;
        if (!warp_pixel(cameras[0], R, t, p.pixel, p.inverse_depth, w)) continue;
        if (!cameras[0].inside(w.pixel.x(), w.pixel.y(), 2.0)) continue;
        points.push_back({w.pixel, w.rho_target, p.normal ? (R * *p.normal).eval() : Eigen::Vector3d::Zero()});
      }
    }
    tracker->set_reference(ref.pyramid, ref.state.affine_a, ref.state.affine_b, ref.exposure, points);
    reference_id = ref.id;
    reference_first_rms = -1.0;
    last_level_rms.clear();
  }

  std::shared_ptr<KeyframeRecord> add_keyframe_record(const OdometryFrame& frame, const SE3& T_cam_world, double a,
                                                      double b, std::int64_t id) {
    auto r = std::make_shared<KeyframeRecord>();
    r->id = id;
    r->frame_index = frame.frame_index;
    r->timestamp_s = frame.timestamp_s;
    r->segment = segment;
    r->T_world_cam = T_cam_world.inverse();
    r->affine_a = a;
    r->affine_b = b;
    keyframes.push_back(r);
    window_records[id] = r;
    return r;
  }

  void make_immature_points(const WindowFrame& f) {
    PixelSelectorOptions so;
    so.wanted = options.immature_points_per_keyframe;
    so.min_gradient = options.min_gradient;
    so.border = 5;
    auto& list = immature[f.id];
    list.clear();
    const PyramidLevel& level = f.pyramid->level(0);
    for (const auto& px : select_pixels(level, so)) list.emplace_back(px, level);
  }

  void trace_immature(const ImagePyramid& pyramid, const SE3& T_cam_world, double a, double b, double exposure) {
    TraceOptions to;
    to.max_search_px = options.max_epipolar_search_px * image_scale;
    to.huber_threshold = options.huber_threshold;
    to.outlier_energy = options.outlier_energy;
    // Each point's search reads only the frames and writes only the point: the points are split
    // over two threads (the same searches, so the same results).
    struct HostTrace {
      std::vector<ImmaturePoint>* list;
      SE3 T_target_host;
      AffineTransfer affine;
    };
    std::vector<HostTrace> hosts;
    std::size_t total = 0;
    for (auto& f : window->frames()) {
      auto it = immature.find(f.id);
      if (it == immature.end()) continue;
      hosts.push_back({&it->second, T_cam_world * f.state.T_cam_world.inverse(),
                       affine_transfer(f.state.affine_a, f.state.affine_b, f.exposure, a, b, exposure)});
      total += it->second.size();
    }
    // Blocks of 64 points alternate between the threads: the cost per point differs by host
    // (older hosts' points are mostly bounded or out of view), so halves would not balance.
    constexpr std::size_t kBlock = 64;
    const odometry::LampGeometry trace_lamp = options.lamp_in_traces ? lamp() : odometry::LampGeometry{};
    auto trace_part = [&](std::size_t part) {
      std::size_t offset = 0;  // index of the host's first point in the concatenation
      for (const HostTrace& host : hosts) {
        for (std::size_t i = 0; i < host.list->size(); ++i)
          if (((offset + i) / kBlock) % 2 == part)
            (*host.list)[i].trace(cameras[0], pyramid.level(0), host.T_target_host, host.affine, to, trace_lamp);
        offset += host.list->size();
      }
    };
    if (total < 4 * kBlock)
      for (std::size_t part = 0; part < 2; ++part) trace_part(part);
    else
      helper.run([&] { trace_part(0); }, [&] { trace_part(1); });
    for (const HostTrace& host : hosts)
      host.list->erase(std::remove_if(host.list->begin(), host.list->end(),
                                      [](const ImmaturePoint& ip) { return ip.outliers() >= 2; }),
                       host.list->end());
  }

  void activate_points() {
    auto& frames_ = window->frames();
    const WindowFrame& newest = frames_.back();
    const LevelCamera& cam = cameras[0];
    // The density that matters is the one the tracker will see: points in the newest keyframe.
    const int wanted = options.points_per_frame;
    int active = 0;
    std::vector<Eigen::Vector2d> projected;
    for (const auto& host : frames_) {
      const SE3 T = newest.state.T_cam_world * host.state.T_cam_world.inverse();
      const Eigen::Matrix3d R = T.rotation_matrix();
      for (const auto& p : host.points) {
        Warp w;
        if (warp_pixel(cam, R, T.translation(), p.pixel, p.inverse_depth, w) && cam.inside(w.pixel.x(), w.pixel.y(), 0.0)) {
          projected.push_back(w.pixel);
          ++active;
        }
      }
    }
    // One point per cell of an occupancy grid in the newest keyframe (DSO's distance map, coarse):
    // a first pass with cells sized for `wanted` points spreads them; a second pass with half the
    // cell size fills in when the first left the window short (texture is rarely uniform).
    for (const double cell_factor : {1.0, 0.5}) {
      if (active >= wanted) break;
      const double cell = cell_factor * std::sqrt(static_cast<double>(cam.width) * cam.height / wanted);
      const int gw = static_cast<int>(std::ceil(cam.width / cell)) + 1;
      const int gh = static_cast<int>(std::ceil(cam.height / cell)) + 1;
      std::vector<char> occupied(static_cast<std::size_t>(gw * gh), 0);
      auto cell_of = [&](const Eigen::Vector2d& px) {
        return static_cast<std::size_t>(static_cast<int>(px.y() / cell) * gw + static_cast<int>(px.x() / cell));
      };
      for (const auto& px : projected) occupied[cell_of(px)] = 1;
      for (std::size_t hi = 0; hi + 1 < frames_.size() && active < wanted; ++hi) {
        WindowFrame& host = frames_[hi];
        auto it = immature.find(host.id);
        if (it == immature.end()) continue;
        const SE3 T = newest.state.T_cam_world * host.state.T_cam_world.inverse();
        const Eigen::Matrix3d R = T.rotation_matrix();
        auto& list = it->second;
        std::vector<ImmaturePoint> keep;
        keep.reserve(list.size());
        for (auto& ip : list) {
          const bool ready = ip.bounded() && ip.quality() >= options.min_trace_quality &&
                             ip.last_interval_px() < options.max_activation_interval_px &&
                             (ip.last_status() == TraceStatus::Good || ip.last_status() == TraceStatus::Skipped ||
                              ip.last_status() == TraceStatus::BadCondition) &&
                             ip.inverse_depth_max() > 0.0;
          if (!ready || active >= wanted) {
            keep.push_back(ip);
            continue;
          }
          const double rho = 0.5 * (ip.inverse_depth_min() + ip.inverse_depth_max());
          Warp w;
          if (!warp_pixel(cam, R, T.translation(), ip.pixel(), rho, w) || !cam.inside(w.pixel.x(), w.pixel.y(), 0.0) ||
              occupied[cell_of(w.pixel)]) {
            keep.push_back(ip);
            continue;
          }
          WindowPoint p;
          p.pixel = ip.pixel();
          p.host_intensity = ip.host_intensity();
          p.inverse_depth = rho;
          window->connect_to_all(p, host.id);
          if (!window->optimize_point(static_cast<int>(hi), p, 5, 1)) continue;  // no fit: dropped
          occupied[cell_of(w.pixel)] = 1;
          projected.push_back(w.pixel);
          host.points.push_back(std::move(p));
          ++active;
        }
        list = std::move(keep);
      }
    }
  }

  // DSO's choice: a keyframe that lost most of its points goes first; otherwise the one whose
  // removal keeps the remaining keyframes best spread (far from the newest, close to others).
  int choose_keyframe_to_marginalise() const {
    const auto& frames_ = window->frames();
    const int n = static_cast<int>(frames_.size());
    const Eigen::Vector3d newest = frames_.back().state.T_cam_world.inverse().translation();
    int best = 0;
    double best_score = -1.0;
    for (int i = 0; i + 2 < n; ++i) {
      const Eigen::Vector3d ti = frames_[static_cast<std::size_t>(i)].state.T_cam_world.inverse().translation();
      double sum = 0.0;
      for (int j = 0; j + 1 < n; ++j) {
        if (j == i) continue;
        sum += 1.0 / ((ti - frames_[static_cast<std::size_t>(j)].state.T_cam_world.inverse().translation()).norm() + 1e-5);
      }
      const double score = std::sqrt((ti - newest).norm() + 1e-9) * sum;
      if (score > best_score) {
        best_score = score;
        best = i;
      }
    }
    return best;
  }

  void marginalise_frames() {
    while (static_cast<int>(window->frames().size()) > options.window_size) {
      int index = -1;
      const auto& frames_ = window->frames();
      for (std::size_t i = 0; i + 2 < frames_.size(); ++i) {
        if (frames_[i].points.size() < 20) {
          index = static_cast<int>(i);
          break;
        }
      }
      if (index < 0) index = choose_keyframe_to_marginalise();
      const WindowFrame removed = window->marginalize_frame(index);
      for (const auto& p : removed.points) archived_points.push_back(to_map_point(removed, p, cameras[0], segment, false));
      auto rec = window_records[removed.id];
      rec->T_world_cam = removed.state.T_cam_world.inverse();
      rec->affine_a = removed.state.affine_a;
      rec->affine_b = removed.state.affine_b;
      rec->marginalised = true;
      window_records.erase(removed.id);
      immature.erase(removed.id);
    }
  }

  void add_keyframe(const OdometryFrame& frame, std::shared_ptr<const ImagePyramid> pyramid, const SE3& T_cam_world,
                    double a, double b, double exposure) {
    WindowFrame f;
    f.id = next_keyframe_id++;
    f.pyramid = std::move(pyramid);
    f.exposure = exposure;
    f.state = {T_cam_world, a, b};
    f.affine_a_prior_weight = a_prior(false);
    f.affine_b_prior_weight = b_prior(false);
    add_keyframe_record(frame, T_cam_world, a, b, f.id);
    const std::int64_t id = f.id;
    window->add_frame(std::move(f));
    for (auto& host : window->frames()) {
      if (host.id == id) continue;
      for (auto& p : host.points) {
        PointResidual r;
        r.target_id = id;
        p.residuals.push_back(r);
      }
    }
  }

  // A keyframe made of a frame the geometric start posed, after a held hand-over: held at that
  // pose in the odometry's scale, so the direction of travel the start found survives the
  // window's optimisations until its frames are past.
  void hold_geometric_keyframe(std::int64_t frame_index) {
    const SE3* T = geometric_pose_of(frame_index);
    if (geometric_scale <= 0.0 || T == nullptr) return;
    WindowFrame& newest = window->frames().back();
    newest.pose_prior_weight = kPosePriorWeight;
    newest.pose_prior = SE3(T->unit_quaternion(), T->translation() * geometric_scale) * segment_origin.inverse();
  }

  // The geometric start's pose of a held frame after its first (nullptr for any other frame).
  const SE3* geometric_pose_of(std::int64_t frame_index) const {
    const std::int64_t k = frame_index - geometric_first_index;
    if (k <= 0 || k >= static_cast<std::int64_t>(geometric_poses.size())) return nullptr;
    return &geometric_poses[static_cast<std::size_t>(k)];
  }

  void map_keyframe() {
    activate_points();
    update_surface_normals();
    window->optimize(options.window_iterations);
    // Points the newest keyframe no longer sees leave the window: those still fitting two
    // keyframes go into the prior, the rest are dropped below.
    if (options.marginalise_points_out_of_view) {
      const std::int64_t newest = window->frames().back().id;
      auto leaving = [newest](const WindowFrame& host, const WindowPoint& p) {
        if (host.id == newest) return false;
        int inliers = 0;
        bool seen = false;
        for (const auto& r : p.residuals) {
          inliers += r.inlier ? 1 : 0;
          seen = seen || (r.target_id == newest && r.inlier);
        }
        return !seen && inliers >= 2;
      };
      for (auto& [host_id, p] : window->marginalize_points(leaving)) {
        const int hi = window->index_of(host_id);
        archived_points.push_back(to_map_point(window->frames()[static_cast<std::size_t>(hi)], p, cameras[0], segment, false));
      }
    }
    for (auto& [host_id, p] : window->remove_bad_points(1, options.drop_points_out_of_newest)) {
      const int hi = window->index_of(host_id);
      archived_points.push_back(to_map_point(window->frames()[static_cast<std::size_t>(hi)], p, cameras[0], segment, false));
    }
    marginalise_frames();
    make_immature_points(window->frames().back());
    sync_records();
    update_tracker_reference();
    frames_since_keyframe = 0;
  }

  // --- the initialiser ---
  OdometryResult initialise(const OdometryFrame& frame, const std::shared_ptr<const ImagePyramid>& pyramid,
                            double exposure, OdometryResult result) {
    result.status = TrackingStatus::Initialising;
    auto restart = [&](const std::string& why) {
      initializer->set_first(pyramid, exposure);
      init_first_index = frame.frame_index;
      init_first_timestamp = frame.timestamp_s;
      init_frames.clear();
      init_T_frame_first.clear();
      init_frames.push_back({frame.frame_index, frame.timestamp_s, segment, nullptr, SE3()});
      init_T_frame_first.push_back(SE3());
      result.message = why;
    };
    if (initializer->state() != InitializerState::Tracking) {
      restart("initialising: first frame");
      return result;
    }
    const InitializerState state = initializer->add_frame(pyramid, exposure);
    result.residual_rms = initializer->rms();
    result.affine_a = initializer->affine_a();
    result.affine_b = initializer->affine_b();
    const int frames_tracked = initializer->frames_tracked();
    // A reference frame that the next frames do not match (a corrupt frame, a cut) is replaced.
    if (state == InitializerState::Failed || initializer->rms() > options.max_tracking_rms ||
        initializer->inlier_fraction() < options.min_tracking_inlier_fraction ||
        std::abs(initializer->affine_a()) > 1.0) {
      restart("initialiser: alignment failed, restarting from this frame");
      return result;
    }
    init_frames.push_back({frame.frame_index, frame.timestamp_s, segment, nullptr, SE3()});
    init_T_frame_first.push_back(initializer->T_frame_first());
    if (state != InitializerState::Succeeded) {
      if (!initializer->snapped() && frames_tracked >= options.init_static_frames) {
        initializer->force_success();
      } else if (frames_tracked >= options.init_max_frames) {
        restart("initialiser: no parallax, restarting from this frame");
        return result;
      } else {
        result.message = "initialising: parallax " + std::to_string(initializer->parallax_px()) + " px";
        return result;
      }
    }

    // Two keyframes: the first frame with the initialiser's points, and this one.
    const SE3 T_first_world = segment_origin.inverse();
    WindowFrame first;
    first.id = next_keyframe_id++;
    first.pyramid = initializer->first_pyramid();
    first.exposure = initializer->first_exposure();
    first.state = {T_first_world, 0.0, 0.0};
    first.affine_a_prior_weight = a_prior(true);
    first.affine_b_prior_weight = b_prior(true);
    first.pose_prior_weight = kPosePriorWeight;
    first.pose_prior = T_first_world;
    const PyramidLevel& first_level = first.pyramid->level(0);
    for (const auto& ip : initializer->points()) {
      if (!ip.good) continue;
      WindowPoint p;
      p.pixel = ip.pixel;
      for (int i = 0; i < kPatternSize; ++i) {
        const auto& o = kPattern[static_cast<std::size_t>(i)];
        p.host_intensity[static_cast<std::size_t>(i)] =
            first_level.at(static_cast<int>(ip.pixel.x()) + o[0], static_cast<int>(ip.pixel.y()) + o[1])[0];
      }
      p.inverse_depth = ip.inverse_depth;
      p.inverse_depth_prior_weight = kInitialPointPriorWeight;
      p.inverse_depth_prior_mean = ip.inverse_depth;
      first.points.push_back(std::move(p));
    }
    OdometryFrame first_frame;
    first_frame.frame_index = init_first_index;
    first_frame.timestamp_s = init_first_timestamp;
    auto first_record = add_keyframe_record(first_frame, T_first_world, 0.0, 0.0, first.id);
    window->add_frame(std::move(first));
    const SE3 T_cam_world = initializer->T_frame_first() * T_first_world;
    add_keyframe(frame, pyramid, T_cam_world, initializer->affine_a(), initializer->affine_b(), exposure);
    const SE3* geometric_pose = geometric_pose_of(frame.frame_index);
    if (options.init_hold_geometric_pose && initializer->aligned_to_geometric_poses() &&
        init_first_index == geometric_first_index && geometric_pose != nullptr &&
        geometric_pose->translation().norm() > 1e-9) {
      // The hand-over keyframe stays where the initialiser put it (its direction of travel from
      // the geometric start): two keyframes leave that direction weakly determined, and the
      // window's own first optimisation turned it by about 20 degrees on the room's starts from
      // frame 30. Held as firmly as the first keyframe's gauge; a softer prior (1e8) kept most
      // of that turn. The later keyframes among the held frames follow (hold_geometric_keyframe).
      WindowFrame& second = window->frames().back();
      second.pose_prior_weight = kPosePriorWeight;
      second.pose_prior = T_cam_world;
      geometric_scale = initializer->T_frame_first().translation().norm() / geometric_pose->translation().norm();
    }
    map_keyframe();
    if (window->point_count() < 50) {
      // The window kept too few of the initialiser's points: try again from this frame.
      for (auto& [id, rec] : window_records) rec->marginalised = true;
      keyframes.erase(std::remove_if(keyframes.begin(), keyframes.end(),
                                     [&](const auto& k) { return window_records.count(k->id) > 0; }),
                      keyframes.end());
      start_segment(segment_origin);
      restart("initialiser: too few points survived the first window, restarting from this frame");
      return result;
    }

    // The initialiser's frames, relative to the first keyframe (the last one is this frame).
    for (std::size_t i = 0; i + 1 < init_frames.size(); ++i) {
      FrameRecord r = init_frames[i];
      r.keyframe = first_record;
      r.T_kf_frame = init_T_frame_first[i].inverse();
      frames.push_back(r);
    }
    const WindowFrame& newest = window->frames().back();
    frames.push_back({frame.frame_index, frame.timestamp_s, segment, window_records[newest.id], SE3()});
    phase = Phase::Tracking;
    previous_T_cam_world = T_first_world;
    last_T_cam_world = newest.state.T_cam_world;
    last_a = newest.state.affine_a;
    last_b = newest.state.affine_b;
    result.status = new_segment_pending ? TrackingStatus::NewSegment : TrackingStatus::Tracking;
    new_segment_pending = false;
    result.is_keyframe = true;
    result.T_world_cam = newest.state.T_cam_world.inverse();
    const InitializerTimings& t = initializer->timings();
    char timing[160];
    std::snprintf(timing, sizeof timing, " (initialiser: %zu hypotheses at the hand-over; %.2f s before the snap, %.2f s aligning)",
                  initializer->hypothesis_count(), t.pre_snap_s, t.align_s);
    result.message = "initialised with " + std::to_string(window->point_count()) + " points" + timing;
    return result;
  }

  // --- tracking ---
  OdometryResult track(const OdometryFrame& frame, const std::shared_ptr<const ImagePyramid>& pyramid,
                       double exposure, OdometryResult result, OdometryTimings& timings) {
    const auto t0 = Clock::now();
    const WindowFrame* ref = &window->frames().back();
    const SE3 T_ref_world = ref->state.T_cam_world;
    const SE3 last = *last_T_cam_world;
    const SE3 velocity = previous_T_cam_world ? last * previous_T_cam_world->inverse() : SE3();
    const Vector6d v = velocity.log();
    std::vector<SE3> hypotheses{velocity * last, SE3::exp(0.5 * v) * last, SE3::exp(2.0 * v) * last, last};
    const double rot = 0.02;
    for (int axis = 0; axis < 3; ++axis) {
      for (const double sign : {-1.0, 1.0}) {
        Vector6d d = Vector6d::Zero();
        d[3 + axis] = sign * rot;
        hypotheses.push_back(SE3::exp(d) * velocity * last);
      }
    }
    TrackingEstimate best;
    bool have_best = false;
    // As DSO: the first hypothesis runs to the end; later ones stop at the first level that is
    // clearly worse than the best so far.
    for (std::size_t i = 0; i < hypotheses.size(); ++i) {
      const SE3 guess = hypotheses[i] * T_ref_world.inverse();
      TrackingEstimate e =
          tracker->track(*pyramid, exposure, guess, last_a, last_b, have_best ? &best.level_rms : nullptr, 1.5);
      if (e.valid && (!have_best || e.rms < best.rms)) {
        best = e;
        have_best = true;
      }
      // Good enough compared with the last frame: stop trying.
      if (have_best && !last_level_rms.empty() && best.rms < 1.2 * last_level_rms[0]) break;
      if (have_best && last_level_rms.empty() && i == 0) break;
    }
    result.residual_rms = best.rms;
    result.residual_count = best.residual_count;
    result.affine_a = best.affine_a;
    result.affine_b = best.affine_b;
    if (!have_best || best.rms > options.max_tracking_rms ||
        best.inlier_fraction < options.min_tracking_inlier_fraction) {
      timings.tracking_ms = ms_since(t0);
      result.status = TrackingStatus::Lost;
      result.message = !have_best ? "lost: alignment failed for every motion hypothesis (" +
                                        std::to_string(tracker->reference_point_count()) + " reference points)"
                                  : (best.rms > options.max_tracking_rms
                                         ? "lost: residual rms " + std::to_string(best.rms) + " above " +
                                               std::to_string(options.max_tracking_rms)
                                         : "lost: inlier fraction " + std::to_string(best.inlier_fraction));
      lose();
      return result;
    }
    last_level_rms = best.level_rms;
    if (reference_first_rms < 0.0) reference_first_rms = best.rms;
    const SE3 T_cam_world = best.T_frame_ref * T_ref_world;
    previous_T_cam_world = last_T_cam_world;
    last_T_cam_world = T_cam_world;
    last_a = best.affine_a;
    last_b = best.affine_b;

    trace_immature(*pyramid, T_cam_world, best.affine_a, best.affine_b, exposure);
    timings.tracking_ms = ms_since(t0);

    // Keyframe decision (DSO's weights; flows relative to w + h).
    ++frames_since_keyframe;
    const double wh = cameras[0].width + cameras[0].height;
    const double brightness = std::abs(best.affine_a - ref->state.affine_a + std::log(exposure / ref->exposure));
    const double score = options.keyframe_translation_flow_weight * best.flow_translation / wh +
                         options.keyframe_full_flow_weight * best.flow_full / wh +
                         options.keyframe_brightness_weight * brightness;
    const bool keyframe = score > 1.0 || 2.0 * reference_first_rms < best.rms ||
                          frames_since_keyframe >= options.max_frames_between_keyframes;
    result.status = TrackingStatus::Tracking;
    if (keyframe) {
      const auto t1 = Clock::now();
      add_keyframe(frame, pyramid, T_cam_world, best.affine_a, best.affine_b, exposure);
      hold_geometric_keyframe(frame.frame_index);
      map_keyframe();
      const WindowFrame& newest = window->frames().back();
      frames.push_back({frame.frame_index, frame.timestamp_s, segment, window_records[newest.id], SE3()});
      last_T_cam_world = newest.state.T_cam_world;
      last_a = newest.state.affine_a;
      last_b = newest.state.affine_b;
      result.is_keyframe = true;
      result.T_world_cam = newest.state.T_cam_world.inverse();
      timings.mapping_ms = ms_since(t1);
    } else {
      frames.push_back({frame.frame_index, frame.timestamp_s, segment, window_records[ref->id],
                        T_ref_world * T_cam_world.inverse()});
      result.T_world_cam = T_cam_world.inverse();
    }
    return result;
  }

  void lose() {
    SE3 origin;
    if (last_T_cam_world) origin = last_T_cam_world->inverse();
    archive_window_points();
    for (auto& [id, rec] : window_records) rec->marginalised = true;
    ++segment;
    new_segment_pending = true;
    start_segment(origin);
  }
};

DirectOdometry::DirectOdometry(const PinholeCamera& camera, OdometryOptions options)
    : options_(options), impl_(std::make_unique<Impl>(camera, options)) {}

DirectOdometry::~DirectOdometry() = default;

OdometryResult DirectOdometry::process(const OdometryFrame& frame) {
  const auto start = Clock::now();
  const LevelCamera& cam = impl_->cameras[0];
  if (frame.image.empty() || frame.image.type() != CV_32FC1)
    throw std::invalid_argument("OdometryFrame.image: expected a CV_32FC1 image");
  if (frame.image.cols != cam.width || frame.image.rows != cam.height)
    throw std::invalid_argument("OdometryFrame.image: size " + std::to_string(frame.image.cols) + "x" +
                                std::to_string(frame.image.rows) + " differs from the camera's " +
                                std::to_string(cam.width) + "x" + std::to_string(cam.height));
  OdometryResult result;
  result.frame_index = frame.frame_index;
  result.timestamp_s = frame.timestamp_s;
  result.segment = impl_->segment;
  if (frame.exposure && !(*frame.exposure > 0.0))
    throw std::invalid_argument("OdometryFrame.exposure: must be positive");
  if (frame.illuminator_power_w && !(*frame.illuminator_power_w >= 0.0))
    throw std::invalid_argument("OdometryFrame.illuminator_power_w: must not be negative");
  if (frame.beam_exponent) {
    if (!std::isfinite(*frame.beam_exponent))
      throw std::invalid_argument("OdometryFrame.beam_exponent: must be finite");
    if (*frame.beam_exponent != impl_->options.beam_exponent) {
      impl_->options.beam_exponent = options_.beam_exponent = *frame.beam_exponent;
      if (impl_->window) impl_->window->set_lamp(impl_->window_lamp());
      if (impl_->tracker) impl_->tracker->set_lamp(impl_->lamp());
    }
  }
  // The brightness factor of the frame: its exposure and, with the lamp's correction, the lamp's
  // power (the only light: irradiance scales with it). A lamp that is off or says nothing
  // counts as 1, so the affine brightness absorbs what changed.
  // The power stays in the exposure while the lamp's factor is not trusted: the window's frames
  // keep the exposures they came with, and a ratio across the switch would jump by P.
  double exposure = frame.exposure.value_or(1.0);
  if (options_.illuminator_correction && frame.illuminator_power_w && *frame.illuminator_power_w > 0.0)
    exposure *= *frame.illuminator_power_w;
  exposure = std::pow(exposure, options_.brightness_exponent);
  // A lamp that is on but not modelled brightens each surface as the rig approaches it, so the
  // exposure no longer explains the brightness change: the affine brightness keeps the free
  // priors, as without exposures. Measured on the twelve bench sequences in `calibrated` mode
  // (README "Illuminator correction"): better on 8 of 12, better than plain odometry on 7
  // instead of 1. With the lamp's factor modelled the strong priors stay (weak ones made the
  // `illuminated` street 1.4-4 times worse).
  const bool lamp_factor_on = options_.illuminator_correction && frame.lamp_factor_trusted;
  const bool unmodelled_lamp = !lamp_factor_on && frame.illuminator_power_w && *frame.illuminator_power_w > 0.0;
  const bool lamp_factor_switched = lamp_factor_on != impl_->lamp_factor_on;
  if (lamp_factor_switched) {
    // Frames already in the window keep the priors they came with; the new ones take the new.
    impl_->lamp_factor_on = lamp_factor_on;
    if (impl_->window) impl_->window->set_lamp(impl_->window_lamp());
    if (impl_->tracker) impl_->tracker->set_lamp(impl_->lamp());
  }
  if (lamp_factor_switched ||
      (impl_->phase == Impl::Phase::Initialising && impl_->initializer->state() != InitializerState::Tracking)) {
    impl_->exposure_explains_brightness = frame.exposure.has_value() && !unmodelled_lamp;
    if (lamp_factor_switched && impl_->tracker)
      impl_->tracker->set_affine_priors(0.1 * impl_->a_prior(false), 0.1 * impl_->b_prior(false));
  }

  // Checked and its beam exponent taken (as without the hold); replayed later.
  if (impl_->geometric_pending && impl_->phase == Impl::Phase::Initialising) return hold_for_geometric_start(frame);

  OdometryTimings timings;
  const auto t0 = Clock::now();
  auto pyramid = std::make_shared<const ImagePyramid>(frame.image, impl_->levels);
  timings.pyramid_ms = ms_since(t0);

  if (impl_->phase == Impl::Phase::Initialising) {
    const auto t1 = Clock::now();
    result = impl_->initialise(frame, pyramid, exposure, result);
    timings.tracking_ms = ms_since(t1);
  } else {
    result = impl_->track(frame, pyramid, exposure, result, timings);
  }
  result.segment = result.status == TrackingStatus::Lost ? impl_->segment - 1 : impl_->segment;
  timings.total_ms = ms_since(start);
  result.timings = timings;
  return result;
}

bool DirectOdometry::exposure_explains_brightness() const { return impl_->exposure_explains_brightness; }

std::vector<PoseStamped> DirectOdometry::trajectory() const {
  std::vector<PoseStamped> out;
  out.reserve(impl_->frames.size());
  for (const auto& f : impl_->frames)
    out.push_back({f.frame_index, f.timestamp_s, f.segment, f.keyframe->T_world_cam * f.T_kf_frame});
  return out;
}

std::vector<KeyframeState> DirectOdometry::keyframes() const {
  std::vector<KeyframeState> out;
  out.reserve(impl_->keyframes.size());
  for (const auto& k : impl_->keyframes) out.push_back(static_cast<const KeyframeState&>(*k));
  return out;
}

std::vector<MapPoint> DirectOdometry::points() const {
  std::vector<MapPoint> out = impl_->archived_points;
  for (const auto& f : impl_->window->frames())
    for (const auto& p : f.points) out.push_back(Impl::to_map_point(f, p, impl_->cameras[0], impl_->segment, true));
  return out;
}

void DirectOdometry::active_points(std::vector<Eigen::Vector3d>& out) const {
  out.clear();
  for (const auto& f : impl_->window->frames())
    for (const auto& p : f.points)
      out.push_back(Impl::to_map_point(f, p, impl_->cameras[0], impl_->segment, true).p_world);
}

OdometryResult DirectOdometry::hold_for_geometric_start(const OdometryFrame& frame) {
  const auto start = Clock::now();
  OdometryResult result;
  result.frame_index = frame.frame_index;
  result.timestamp_s = frame.timestamp_s;
  result.segment = impl_->segment;
  GeometricStart& geometric = *impl_->geometric;
  if (impl_->geometric_frames.empty())
    geometric.set_first(frame.image);
  else
    geometric.add_frame(frame.image);
  OdometryFrame held = frame;
  held.image = frame.image.clone();  // the caller may reuse its buffer
  impl_->geometric_frames.push_back(std::move(held));
  if (!geometric.complete()) {
    result.status = TrackingStatus::Initialising;
    result.message = "initialising: geometric start, frame " + std::to_string(geometric.frames()) + " of " +
                     std::to_string(impl_->options.init_geometric_frames);
    result.timings.tracking_ms = result.timings.total_ms = ms_since(start);
    return result;
  }
  impl_->geometric_pending = false;
  const GeometricStartResult solved = geometric.solve();
  std::vector<OdometryFrame> frames = std::move(impl_->geometric_frames);
  impl_->geometric_frames.clear();
  impl_->geometric_poses = solved.ok ? solved.T_frame_first : std::vector<SE3>{};
  impl_->geometric_first_index = frames.front().frame_index;
  std::string hand_over;
  bool new_segment = false;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    result = process(frames[i]);
    new_segment = new_segment || result.status == TrackingStatus::NewSegment;
    if (i == 0 && solved.ok && impl_->phase == Impl::Phase::Initialising && !impl_->geometric_pending &&
        impl_->init_first_index == frames[0].frame_index)
      impl_->initializer->set_geometric_poses(solved.T_frame_first);
    if (result.message.rfind("initialised with", 0) == 0) hand_over = result.message;
  }
  // The caller sees only this frame's result: a segment begun among the replayed frames is new
  // to it here.
  if (new_segment && result.status == TrackingStatus::Tracking) result.status = TrackingStatus::NewSegment;
  // The hand-over's message (the pipeline logs it) and what the geometric start gave.
  const std::string geometric_summary =
      (solved.ok ? "geometric start: " : "geometric start not used: ") + solved.reason;
  result.message = hand_over.empty() ? geometric_summary : hand_over + "; " + geometric_summary;
  result.timings.total_ms = ms_since(start);
  return result;
}

void DirectOdometry::reset() {
  const auto& c = impl_->cameras[0];
  const PinholeCamera camera(c.width, c.height, Eigen::Vector4d(c.fx, c.fy, c.cx, c.cy));
  impl_ = std::make_unique<Impl>(camera, options_);
}

}  // namespace nirslam
