#include "nirslam/sim/renderer.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <numeric>
#include <stdexcept>

#include <opencv2/core.hpp>

#include "kernels.hpp"
#include "nirslam/sim/texture.hpp"

namespace nirslam::sim {

namespace {

using Eigen::Matrix3f;
using Eigen::Vector3f;

constexpr int kTileSize = 16;
constexpr int kMaxSamples = 16;  // 4 x 4
constexpr int kBeamLutSize = 1024;
constexpr float kInvPi = static_cast<float>(1.0 / std::numbers::pi);

// Per time slot: where the camera and the light are.
struct SlotState {
  Matrix3f R;           // R_world_cam
  Vector3f centre;      // camera centre
  Vector3f light;       // light position
  Vector3f beam_axis;   // optical axis in the world
  Vector3f mirror_centre;  // camera centre mirrored in the glossy floor
};

// What the culling sorts and tests: a primitive, or a group of primitives behind one box.
struct Unit {
  int index;  // primitive index, or -(group + 1)
  int count;  // members that follow a group's entry in a candidate list (0 for a primitive)
  bool unbounded;
  Vector3f centre;
  float radius;
};

std::vector<Unit> make_units(const Scene& scene) {
  std::vector<Unit> units;
  std::vector<bool> grouped(scene.primitives.size(), false);
  for (std::size_t g = 0; g < scene.groups.size(); ++g) {
    const PrimitiveGroup& group = scene.groups[g];
    units.push_back({-static_cast<int>(g) - 1, group.count, false, 0.5f * (group.lo + group.hi), 0.5f * (group.hi - group.lo).norm()});
    for (int i = 0; i < group.count; ++i) grouped[static_cast<std::size_t>(group.first + i)] = true;
  }
  for (std::size_t i = 0; i < scene.primitives.size(); ++i) {
    if (grouped[i]) continue;
    const Primitive& p = scene.primitives[i];
    units.push_back({static_cast<int>(i), 0, p.unbounded(), p.unbounded() ? Vector3f(Vector3f::Zero()) : p.bound_centre(),
                     p.unbounded() ? 0.0f : p.bound_radius()});
  }
  return units;
}

// A unit's bounding sphere as seen from an apex: direction, angular radius and the distance from
// the apex to the sphere (0 for unbounded units and spheres holding the apex).
struct SphereView {
  Vector3f dir;
  float cos_g, sin_g;
  float near;
  bool always;
};

struct Candidate {
  int index;  // primitive, or -(group + 1) followed by the group's `skip` members
  float near;  // no hit of this primitive is closer to the apex than this
  int skip;
};

// The views of every unit from an apex, and the unit order by increasing `near`, so that tracing
// can stop at the first candidate farther than the best hit so far.
void view_units(const std::vector<Unit>& units, const Vector3f& apex, std::vector<SphereView>& out, std::vector<int>& order) {
  out.resize(units.size());
  for (std::size_t i = 0; i < units.size(); ++i) {
    const Unit& u = units[i];
    SphereView& v = out[i];
    v.near = 0.0f;
    v.always = u.unbounded;
    if (v.always) continue;
    const Vector3f rel = u.centre - apex;
    const float dist = rel.norm();
    v.always = dist <= u.radius * 1.001f + 1e-3f;
    if (v.always) continue;
    v.near = std::max(0.0f, (dist - u.radius) * 0.999f - 1e-3f);
    v.dir = rel / dist;
    v.sin_g = u.radius / dist;
    v.cos_g = std::sqrt(std::max(0.0f, 1.0f - v.sin_g * v.sin_g));
  }
  order.resize(out.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return out[static_cast<std::size_t>(a)].near < out[static_cast<std::size_t>(b)].near;
  });
}

// Units whose bounding sphere meets the cone (axis, half angle phi) from the apex, nearest first.
void cull(const Scene& scene, const std::vector<Unit>& units, const std::vector<SphereView>& views,
          const std::vector<int>& order, const Vector3f& axis, float cos_phi, float sin_phi, std::vector<Candidate>& out) {
  out.clear();
  for (const int i : order) {
    const SphereView& v = views[static_cast<std::size_t>(i)];
    if (!(v.always || axis.dot(v.dir) >= cos_phi * v.cos_g - sin_phi * v.sin_g)) continue;
    const Unit& u = units[static_cast<std::size_t>(i)];
    out.push_back({u.index, v.near, u.count});
    if (u.index < 0) {
      const PrimitiveGroup& g = scene.groups[static_cast<std::size_t>(-u.index - 1)];
      for (int m = 0; m < g.count; ++m) out.push_back({g.first + m, v.near, 0});
    }
  }
}

struct Shader {
  const Scene& scene;
  const std::vector<detail::YawCache>& yaw;
  float j0;
  float ambient;
  float sky;
  const std::array<float, kBeamLutSize + 1>& beam_lut;
  float fixed_footprint = 0.0f;  // ShadingOptions::texture_footprint_m
  bool glossy = true;            // ShadingOptions::glossy_floor

  float beam(float cos_alpha) const {
    if (cos_alpha <= 0.0f) return 0.0f;
    const float x = std::min(cos_alpha, 1.0f) * kBeamLutSize;
    const int i = std::min(static_cast<int>(x), kBeamLutSize - 1);
    const float f = x - static_cast<float>(i);
    return beam_lut[static_cast<std::size_t>(i)] * (1.0f - f) + beam_lut[static_cast<std::size_t>(i) + 1] * f;
  }

  // Nearest hit among candidates sorted by `near` from an apex that lies `offset` behind the
  // ray's origin on the ray's line.
  int trace(const detail::Ray& ray, const std::vector<Candidate>& candidates, float& t, int& face,
            float offset = 0.0f) const {
    int best = -1;
    t = std::numeric_limits<float>::infinity();
    const std::size_t n = candidates.size();
    for (std::size_t k = 0; k < n; ++k) {
      const Candidate& c = candidates[k];
      if (c.near - offset >= t) break;
      if (c.index < 0) {  // a group: skip its members when the ray misses its box
        const PrimitiveGroup& g = scene.groups[static_cast<std::size_t>(-c.index - 1)];
        float tn, tf;
        detail::slab(g.lo, g.hi, ray.o, ray.inv, tn, tf);
        if (!(tn <= tf && tf > detail::kEpsilon && tn < t)) k += static_cast<std::size_t>(c.skip);
        continue;
      }
      const float tc = detail::hit_distance(scene.primitives[static_cast<std::size_t>(c.index)],
                                            yaw[static_cast<std::size_t>(c.index)], ray);
      if (tc < t) {
        t = tc;
        best = c.index;
      }
    }
    if (best >= 0)
      face = detail::hit_face(scene.primitives[static_cast<std::size_t>(best)], yaw[static_cast<std::size_t>(best)], ray);
    return best;
  }

  // The nearest hits of a packet of four rays; best holds primitive indices (-1: none). Each lane
  // gets exactly the hit a packet of four copies of its own ray would get: a lane stops taking
  // hits where its own ray would have stopped tracing (a candidate's `near` beyond its best hit)
  // and takes no hit from the members of a group whose box its ray misses, so packets of
  // neighbouring pixels render the same image as packets of one pixel's subsamples.
  void trace4(const detail::Packet& packet, const std::vector<Candidate>& candidates, detail::Array4f& t,
              Eigen::Array4i& best) const {
    using Mask = Eigen::Array<bool, 4, 1>;
    t = detail::Array4f::Constant(std::numeric_limits<float>::infinity());
    detail::Array4f best_f = detail::Array4f::Constant(-1.0f);
    Mask in_group = Mask::Constant(true);
    std::size_t group_end = 0;  // candidates before this index belong to the group being traced
    const std::size_t n = candidates.size();
    for (std::size_t k = 0; k < n; ++k) {
      const Candidate& c = candidates[k];
      if (c.near >= t.maxCoeff()) break;
      if (k >= group_end) in_group = Mask::Constant(true);
      if (c.index < 0) {
        const PrimitiveGroup& g = scene.groups[static_cast<std::size_t>(-c.index - 1)];
        detail::Array4f tn, tf;
        detail::slab4(g.lo, g.hi, packet.o, packet.ix, packet.iy, packet.iz, tn, tf);
        in_group = (tn <= tf) && (tf > detail::kEpsilon) && (tn < t);
        group_end = k + 1 + static_cast<std::size_t>(c.skip);
        if (!in_group.any()) k = group_end - 1;
        continue;
      }
      const detail::Array4f tc = detail::hit_distance4(scene.primitives[static_cast<std::size_t>(c.index)],
                                                       yaw[static_cast<std::size_t>(c.index)], packet);
      const Mask closer = (tc < t) && (detail::Array4f::Constant(c.near) < t) && in_group;  // evaluated now: t changes below
      best_f = closer.select(detail::Array4f::Constant(static_cast<float>(c.index)), best_f);
      t = closer.select(tc, t);
    }
    best = best_f.cast<int>();
  }

  // Radiance leaving point x of primitive `prim` (face) towards a viewer looking along unit d;
  // `path` is the distance the viewing ray travelled (for the texture footprint).
  float shade(int prim, int face, const Vector3f& x, const Vector3f& d, float path, float pixel_angle,
              const SlotState& slot, const std::vector<Candidate>* mirror_candidates, float* albedo_out = nullptr,
              float* irradiance_out = nullptr) const {
    const Primitive& p = scene.primitives[static_cast<std::size_t>(prim)];
    const detail::Surface s = detail::surface_at(p, yaw[static_cast<std::size_t>(prim)], face, x);
    Vector3f n = s.normal;
    float n_dot_d = n.dot(d);
    if (n_dot_d > 0.0f) {
      n = -n;
      n_dot_d = -n_dot_d;
    }
    const float footprint =
        fixed_footprint > 0.0f ? fixed_footprint : path * pixel_angle / std::max(-n_dot_d, 0.15f);
    const float albedo =
        std::clamp(material_albedo(s.material, s.u, s.v, footprint, p.seed) * p.albedo_scale, 0.0f, 1.0f);
    const Vector3f l = x - slot.light;
    const float d2 = std::max(l.squaredNorm(), 1e-6f);
    const float inv_d = 1.0f / std::sqrt(d2);
    const float cos_theta = std::max(0.0f, -n.dot(l) * inv_d);
    const float irradiance = j0 * beam(l.dot(slot.beam_axis) * inv_d) * cos_theta / d2 + ambient * 0.5f * (1.0f + n.z());
    float radiance = albedo * kInvPi * irradiance;
    if (albedo_out) *albedo_out = albedo;
    if (irradiance_out) *irradiance_out = irradiance;

    if (glossy && mirror_candidates && scene.glossy_floor && face == 5 && std::fabs(x.z() - scene.glossy_floor->z) < 1e-3f &&
        d.z() < 0.0f) {
      const GlossyFloor& g = *scene.glossy_floor;
      const float c = 1.0f - std::min(-d.z(), 1.0f);
      const float c2 = c * c;
      const float fresnel = g.strength * (g.r0 + (1.0f - g.r0) * c2 * c2 * c);
      const Vector3f dr(d.x(), d.y(), -d.z());
      const detail::Ray ray = detail::make_ray(x, dr);
      float t = 0.0f;
      int rface = 0;
      const int hit = trace(ray, *mirror_candidates, t, rface, (x - slot.mirror_centre).norm());
      // A floor coating is not a clean mirror: its image is blurred, here by filtering the
      // reflected texture to at least 5 cm (which also keeps the second shading cheap).
      const float blur_angle = std::max(pixel_angle, 0.05f / (path + t));
      const float reflected = hit < 0 ? sky : shade(hit, rface, x + t * dr, dr, path + t, blur_angle, slot, nullptr);
      radiance = (1.0f - fresnel) * radiance + fresnel * reflected;
    }
    return radiance;
  }
};

std::array<float, kBeamLutSize + 1> make_beam_lut(const Illuminator& light) {
  std::array<float, kBeamLutSize + 1> lut{};
  const double m = light.beam_exponent();
  for (int i = 0; i <= kBeamLutSize; ++i)
    lut[static_cast<std::size_t>(i)] = static_cast<float>(std::pow(static_cast<double>(i) / kBeamLutSize, m));
  return lut;
}

// What a Shader reads by reference, built once per frame (or per probed pixel).
struct ShadingTables {
  ShadingTables(const Scene& scene_in, const Illuminator& light) : scene(scene_in), yaw(scene_in.primitives.size()),
                                                                    beam_lut(make_beam_lut(light)) {
    for (std::size_t i = 0; i < yaw.size(); ++i)
      yaw[i] = {std::cos(scene.primitives[i].yaw), std::sin(scene.primitives[i].yaw)};
  }
  Shader shader(const Lighting& lighting, const ShadingOptions& shading) const {
    return Shader{scene,
                  yaw,
                  static_cast<float>(lighting.illuminator.axial_intensity()),
                  static_cast<float>(lighting.ambient_irradiance),
                  static_cast<float>(lighting.sky_radiance),
                  beam_lut,
                  static_cast<float>(shading.texture_footprint_m),
                  shading.glossy_floor};
  }

  const Scene& scene;
  std::vector<detail::YawCache> yaw;
  std::array<float, kBeamLutSize + 1> beam_lut;
};

SlotState slot_state(const SE3& pose, const Illuminator& light, const Scene& scene) {
  SlotState s;
  s.R = pose.rotation_matrix().cast<float>();
  s.centre = pose.translation().cast<float>();
  s.light = (pose * light.offset_cam).cast<float>();
  s.beam_axis = s.R.col(2);
  s.mirror_centre = s.centre;
  if (scene.glossy_floor) s.mirror_centre.z() = 2.0f * scene.glossy_floor->z - s.centre.z();
  return s;
}

}  // namespace

// ---------------------------------------------------------------------------------------------

double Illuminator::beam_exponent() const {
  const double half = half_angle_deg * std::numbers::pi / 180.0;
  if (!(half > 0.0 && half < std::numbers::pi / 2))
    throw std::invalid_argument("illuminator half angle must be in (0, 90) degrees");
  return std::log(0.5) / std::log(std::cos(half));
}

double Illuminator::beam(double alpha_rad) const {
  const double c = std::cos(alpha_rad);
  return c <= 0.0 ? 0.0 : std::pow(c, beam_exponent());
}

double Illuminator::axial_intensity() const {
  return efficiency * power_w * (beam_exponent() + 1.0) / (2.0 * std::numbers::pi);
}

Renderer::Renderer(std::shared_ptr<const Scene> scene, std::shared_ptr<const CameraModel> camera, int supersampling,
                   ShadingOptions shading)
    : scene_(std::move(scene)), camera_(std::move(camera)), ss_(supersampling), shading_(shading) {
  if (!scene_ || !camera_) throw std::invalid_argument("renderer: scene and camera are required");
  if (ss_ < 1 || ss_ > 4) throw std::invalid_argument("renderer: supersampling must be 1..4");
  if (scene_->primitives.size() > 4096) throw std::invalid_argument("renderer: too many primitives");
  if (!(shading_.texture_footprint_m >= 0.0 && shading_.texture_footprint_m <= 10.0))
    throw std::invalid_argument("renderer: texture footprint must be 0..10 m");
  width_ = camera_->width();
  height_ = camera_->height();
  build_rays();
}

int Renderer::slot_of(int sx, int sy) const {
  // Subsample k = sy * ss + sx takes time slot (k * p) mod n with p coprime to n, about 0.62 n,
  // so neighbouring subsamples are far apart in time.
  const int n = ss_ * ss_;
  if (n == 1) return 0;
  int p = std::max(1, static_cast<int>(std::lround(0.618 * n)));
  while (std::gcd(p, n) != 1) ++p;
  return ((sy * ss_ + sx) * p) % n;
}

void Renderer::build_rays() {
  // Rays are stored tile by tile (pixels of a tile in row order, the subsamples of a pixel
  // together), the order render() reads them in: one linear stream per frame.
  const int samples = ss_ * ss_;
  const std::size_t pixels = static_cast<std::size_t>(width_) * static_cast<std::size_t>(height_);
  sample_dirs_.assign(pixels * static_cast<std::size_t>(samples), Vector3f::Zero());
  centre_dirs_.assign(pixels, Vector3f::Zero());
  pixel_angle_.assign(pixels, 0.0f);
  auto ray = [&](double u, double v) -> Vector3f {
    const auto r = camera_->unproject(Eigen::Vector2d(u, v));
    return r ? Vector3f(r->normalized().cast<float>()) : Vector3f(Vector3f::Zero());
  };
  tiles_.clear();
  std::size_t next = 0;
  for (int y0 = 0; y0 < height_; y0 += kTileSize) {
    for (int x0 = 0; x0 < width_; x0 += kTileSize) {
      Tile tile{x0, y0, std::min(x0 + kTileSize, width_), std::min(y0 + kTileSize, height_), next,
                Vector3f::Zero(), 1.0f, 0.0f};
      Vector3f sum = Vector3f::Zero();
      for (int y = tile.y0; y < tile.y1; ++y) {
        for (int x = tile.x0; x < tile.x1; ++x, ++next) {
          for (int sy = 0; sy < ss_; ++sy)
            for (int sx = 0; sx < ss_; ++sx) {
              Vector3f& d = sample_dirs_[next * static_cast<std::size_t>(samples) + static_cast<std::size_t>(sy * ss_ + sx)];
              d = ray(x + (sx + 0.5) / ss_ - 0.5, y + (sy + 0.5) / ss_ - 0.5);
              sum += d;
            }
          centre_dirs_[next] = ray(x, y);
          sum += centre_dirs_[next];
          const Vector3f right = ray(x + 0.5, y), left = ray(x - 0.5, y);
          const Vector3f down = ray(x, y + 0.5), up = ray(x, y - 0.5);
          const float angle = std::max((right - left).norm(), (down - up).norm());
          pixel_angle_[next] = std::isfinite(angle) ? angle : 0.0f;
        }
      }
      tile.axis = sum.norm() > 0.0f ? Vector3f(sum.normalized()) : Vector3f(0.0f, 0.0f, 1.0f);
      float cos_min = 1.0f;
      for (std::size_t p = tile.offset; p < next; ++p)
        for (int s = -1; s < samples; ++s) {
          const Vector3f& d = s < 0 ? centre_dirs_[p] : sample_dirs_[p * static_cast<std::size_t>(samples) + static_cast<std::size_t>(s)];
          if (d.squaredNorm() > 0.0f) cos_min = std::min(cos_min, tile.axis.dot(d));
        }
      // A little margin for float rounding in the culling test.
      const float half = std::acos(std::clamp(cos_min, -1.0f, 1.0f)) + 1e-3f;
      tile.cos_half = std::cos(half);
      tile.sin_half = std::sin(half);
      tiles_.push_back(tile);
    }
  }
}

void Renderer::render(std::span<const SE3> poses, const Lighting& lighting, cv::Mat& radiance, cv::Mat* depth) const {
  const int slots = static_cast<int>(poses.size());
  if (slots != 1 && slots != time_slots())
    throw std::invalid_argument("renderer: expected 1 pose or one per time slot (" + std::to_string(time_slots()) + ")");
  radiance.create(height_, width_, CV_32FC1);
  if (depth) depth->create(height_, width_, CV_32FC1);

  const Scene& scene = *scene_;
  const ShadingTables tables(scene, lighting.illuminator);
  const Shader shader = tables.shader(lighting, shading_);

  const std::vector<Unit> units = make_units(scene);
  std::vector<SlotState> state;
  const auto n_slots = static_cast<std::size_t>(slots);
  std::vector<std::vector<SphereView>> views(n_slots), mirror_views(n_slots);
  std::vector<std::vector<int>> order(n_slots), mirror_order(n_slots);
  for (std::size_t k = 0; k < n_slots; ++k) {
    state.push_back(slot_state(poses[k], lighting.illuminator, scene));
    view_units(units, state.back().centre, views[k], order[k]);
    if (scene.glossy_floor && shading_.glossy_floor) view_units(units, state.back().mirror_centre, mirror_views[k], mirror_order[k]);
  }
  const int middle = slots / 2;
  const bool blur = slots > 1;
  const int samples = ss_ * ss_;
  std::array<int, kMaxSamples> slot_of_sample{};
  for (int sy = 0; sy < ss_; ++sy)
    for (int sx = 0; sx < ss_; ++sx) slot_of_sample[static_cast<std::size_t>(sy * ss_ + sx)] = blur ? slot_of(sx, sy) : 0;

  // The hits of up to four neighbouring pixels of one row, one sample each (lanes past `count`
  // repeat the last pixel).
  struct RowHits {
    std::array<int, 4> prim{}, face{};
    std::array<float, 4> dist{};
    std::array<Vector3f, 4> dir;
  };
  const bool row_packets = samples == 1 && !blur;
  const auto trace_row_packet = [&](const SlotState& st, const std::vector<Candidate>& candidates, const Vector3f* first_dir,
                                    int count, RowHits& hits) {
    detail::Array4f dx, dy, dz;
    for (int l = 0; l < 4; ++l) {
      const auto i = static_cast<std::size_t>(std::min(l, count - 1));
      const bool valid = first_dir[i].squaredNorm() > 0.0f;
      hits.dir[static_cast<std::size_t>(l)] = valid ? Vector3f(st.R * first_dir[i]) : Vector3f(st.R.col(2));
      dx[l] = hits.dir[static_cast<std::size_t>(l)].x();
      dy[l] = hits.dir[static_cast<std::size_t>(l)].y();
      dz[l] = hits.dir[static_cast<std::size_t>(l)].z();
    }
    const detail::Packet packet = detail::make_packet(st.centre, dx, dy, dz);
    detail::Array4f t;
    Eigen::Array4i best;
    shader.trace4(packet, candidates, t, best);
    for (int l = 0; l < count; ++l) {
      const auto i = static_cast<std::size_t>(l);
      hits.dist[i] = t[l];
      hits.prim[i] = first_dir[i].squaredNorm() > 0.0f ? best[l] : -2;
      if (hits.prim[i] >= 0)
        hits.face[i] = detail::hit_face_at(scene.primitives[static_cast<std::size_t>(hits.prim[i])],
                                           tables.yaw[static_cast<std::size_t>(hits.prim[i])], st.centre + t[l] * hits.dir[i]);
    }
  };

  const auto body = [&](const cv::Range& range) {
    std::vector<std::vector<Candidate>> direct(n_slots), mirrored(n_slots);
    RowHits row_hits;
    for (auto& v : direct) v.reserve(scene.primitives.size() + scene.groups.size());
    for (auto& v : mirrored) v.reserve(scene.primitives.size() + scene.groups.size());
    for (int ti = range.start; ti < range.end; ++ti) {
      const Tile& tile = tiles_[static_cast<std::size_t>(ti)];
      for (int k = 0; k < slots; ++k) {
        const Vector3f axis = state[static_cast<std::size_t>(k)].R * tile.axis;
        const auto kk = static_cast<std::size_t>(k);
        cull(scene, units, views[kk], order[kk], axis, tile.cos_half, tile.sin_half, direct[kk]);
        if (scene.glossy_floor && shading_.glossy_floor)
          cull(scene, units, mirror_views[kk], mirror_order[kk], Vector3f(axis.x(), axis.y(), -axis.z()), tile.cos_half, tile.sin_half,
               mirrored[kk]);
      }
      std::size_t p = tile.offset;
      for (int y = tile.y0; y < tile.y1; ++y) {
        float* out = radiance.ptr<float>(y);
        float* depth_row = depth ? depth->ptr<float>(y) : nullptr;
        for (int x = tile.x0; x < tile.x1; ++x, ++p) {
          const float pixel_angle = pixel_angle_[p];
          // Trace every subsample: in packets of four rays without motion blur (one pose), one by
          // one with it (each subsample has its own pose). With one sample a pixel, a packet holds
          // the pixel and the three after it in the row, traced when the first of them is reached.
          std::array<int, kMaxSamples> prim{}, face{};
          std::array<float, kMaxSamples> dist{};
          std::array<Vector3f, kMaxSamples> dir;
          const Vector3f* dcs = &sample_dirs_[p * static_cast<std::size_t>(samples)];
          if (row_packets) {
            const int lane = (x - tile.x0) % 4;
            if (lane == 0) trace_row_packet(state[0], direct[0], dcs, std::min(4, tile.x1 - x), row_hits);
            prim[0] = row_hits.prim[static_cast<std::size_t>(lane)];
            face[0] = row_hits.face[static_cast<std::size_t>(lane)];
            dist[0] = row_hits.dist[static_cast<std::size_t>(lane)];
            dir[0] = row_hits.dir[static_cast<std::size_t>(lane)];
          } else if (!blur) {
            const SlotState& st = state[0];
            for (int s0 = 0; s0 < samples; s0 += 4) {
              detail::Array4f dx, dy, dz;
              for (int l = 0; l < 4; ++l) {
                const auto s = static_cast<std::size_t>(std::min(s0 + l, samples - 1));
                const bool valid = dcs[s].squaredNorm() > 0.0f;
                dir[s] = valid ? Vector3f(st.R * dcs[s]) : Vector3f(st.R.col(2));
                dx[l] = dir[s].x();
                dy[l] = dir[s].y();
                dz[l] = dir[s].z();
              }
              const detail::Packet packet = detail::make_packet(st.centre, dx, dy, dz);
              detail::Array4f t;
              Eigen::Array4i best;
              shader.trace4(packet, direct[0], t, best);
              for (int l = 0; l < 4 && s0 + l < samples; ++l) {
                const auto s = static_cast<std::size_t>(s0 + l);
                dist[s] = t[l];
                prim[s] = dcs[s].squaredNorm() > 0.0f ? best[l] : -2;
                if (prim[s] >= 0)
                  face[s] = detail::hit_face_at(scene.primitives[static_cast<std::size_t>(prim[s])],
                                                tables.yaw[static_cast<std::size_t>(prim[s])], st.centre + t[l] * dir[s]);
              }
            }
          } else {
            for (int s = 0; s < samples; ++s) {
              const auto si = static_cast<std::size_t>(s);
              if (dcs[si].squaredNorm() == 0.0f) {
                prim[si] = -2;
                continue;
              }
              const int k = slot_of_sample[si];
              const SlotState& st = state[static_cast<std::size_t>(k)];
              dir[si] = st.R * dcs[si];
              prim[si] = shader.trace(detail::make_ray(st.centre, dir[si]), direct[static_cast<std::size_t>(k)], dist[si], face[si]);
            }
          }
          float sum = 0.0f;
          if (blur) {
            for (int s = 0; s < samples; ++s) {
              const auto si = static_cast<std::size_t>(s);
              if (prim[si] == -2) continue;
              if (prim[si] < 0) {
                sum += shader.sky;
                continue;
              }
              const int k = slot_of_sample[si];
              const SlotState& st = state[static_cast<std::size_t>(k)];
              const Vector3f xw = st.centre + dist[si] * dir[si];
              sum += shader.shade(prim[si], face[si], xw, dir[si], dist[si], pixel_angle / static_cast<float>(ss_), st,
                                  scene.glossy_floor ? &mirrored[static_cast<std::size_t>(k)] : nullptr);
            }
          } else {
            // Multisample shading: one shading per (primitive, face) group at its mean hit.
            std::array<bool, kMaxSamples> done{};
            const SlotState& st = state[0];
            for (int s = 0; s < samples; ++s) {
              const auto si = static_cast<std::size_t>(s);
              if (done[si] || prim[si] == -2) continue;
              if (prim[si] < 0) {
                sum += shader.sky;
                continue;
              }
              Vector3f point_sum = Vector3f::Zero(), dir_sum = Vector3f::Zero();
              float dist_sum = 0.0f;
              int count = 0;
              for (int q = s; q < samples; ++q) {
                const auto qi = static_cast<std::size_t>(q);
                if (done[qi] || prim[qi] != prim[si] || face[qi] != face[si]) continue;
                done[qi] = true;
                point_sum += dir[qi] * dist[qi];
                dir_sum += dir[qi];
                dist_sum += dist[qi];
                ++count;
              }
              const float inv = 1.0f / static_cast<float>(count);
              const Vector3f xw = st.centre + point_sum * inv;
              const Vector3f d = dir_sum.normalized();
              sum += static_cast<float>(count) *
                     shader.shade(prim[si], face[si], xw, d, dist_sum * inv, pixel_angle, st,
                                  scene.glossy_floor ? &mirrored[0] : nullptr);
            }
          }
          out[x] = sum / static_cast<float>(samples);
          if (depth_row) {
            const Vector3f& dc = centre_dirs_[p];
            float z = 0.0f;
            if (dc.squaredNorm() > 0.0f) {
              const SlotState& st = state[static_cast<std::size_t>(middle)];
              const detail::Ray ray = detail::make_ray(st.centre, st.R * dc);
              float t = 0.0f;
              int f = 0;
              if (shader.trace(ray, direct[static_cast<std::size_t>(middle)], t, f) >= 0) z = t * dc.z();
            }
            depth_row[x] = z;
          }
        }
      }
    }
  };
  const int tile_count = static_cast<int>(tiles_.size());
  cv::parallel_for_(cv::Range(0, tile_count), body, std::max(1.0, tile_count / 8.0));
}

Renderer::PixelSample Renderer::render_pixel(const SE3& pose, const Lighting& lighting, const Eigen::Vector2d& pixel) const {
  PixelSample sample;
  const auto ray_cam = camera_->unproject(pixel);
  if (!ray_cam) return sample;
  const Scene& scene = *scene_;
  const ShadingTables tables(scene, lighting.illuminator);
  const Shader shader = tables.shader(lighting, shading_);
  const SlotState st = slot_state(pose, lighting.illuminator, scene);
  std::vector<Candidate> all(scene.primitives.size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = {static_cast<int>(i), 0.0f, 0};
  const Eigen::Vector3d dir_world = pose.rotation_matrix() * ray_cam->normalized();
  sample.hit = cast_ray(scene, pose.translation(), dir_world);
  if (!sample.hit) {
    sample.radiance = lighting.sky_radiance;
    return sample;
  }
  const Vector3f d = dir_world.cast<float>();
  const detail::Ray ray = detail::make_ray(st.centre, d);
  float t = 0.0f;
  int face = 0;
  const int prim = shader.trace(ray, all, t, face);
  const float pixel_angle = static_cast<float>(1.0 / camera_->fx());
  float albedo = 0.0f, irradiance = 0.0f;
  sample.radiance = shader.shade(prim, face, st.centre + t * d, d, t, pixel_angle, st, &all, &albedo, &irradiance);
  sample.albedo = albedo;
  sample.irradiance = irradiance;
  return sample;
}

}  // namespace nirslam::sim
