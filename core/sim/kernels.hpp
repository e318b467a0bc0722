#pragma once

// Ray-primitive intersection kernels shared by cast_ray() and the renderer (private to core/sim).
// Float arithmetic, no allocation; a ray is origin o + t d with precomputed 1/d.

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Core>

#include "nirslam/sim/scene.hpp"

namespace nirslam::sim::detail {

constexpr float kEpsilon = 1e-4f;  // hits closer than this are ignored (surface acne)
constexpr int kCurvedFace = 6;

struct Ray {
  Eigen::Vector3f o;
  Eigen::Vector3f d;
  Eigen::Vector3f inv;  // 1 / d, +-inf for zero components
};

inline Ray make_ray(const Eigen::Vector3f& o, const Eigen::Vector3f& d) {
  return {o, d, Eigen::Vector3f(1.0f / d.x(), 1.0f / d.y(), 1.0f / d.z())};
}

// Precomputed per-primitive constants for YawBox (cos, sin) to keep trig out of the hot loop.
struct YawCache {
  float c = 1.0f, s = 0.0f;
};

constexpr float kInfinity = std::numeric_limits<float>::infinity();

// Slab test without data-dependent branches (they mispredict on every other ray): the entry and
// exit distances of the ray through the box [lo, hi].
inline void slab(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, const Eigen::Vector3f& o,
                 const Eigen::Vector3f& inv, float& t_near, float& t_far) {
  const float ax = (lo.x() - o.x()) * inv.x(), bx = (hi.x() - o.x()) * inv.x();
  const float ay = (lo.y() - o.y()) * inv.y(), by = (hi.y() - o.y()) * inv.y();
  const float az = (lo.z() - o.z()) * inv.z(), bz = (hi.z() - o.z()) * inv.z();
  t_near = std::max(std::max(std::min(ax, bx), std::min(ay, by)), std::min(az, bz));
  t_far = std::min(std::min(std::max(ax, bx), std::max(ay, by)), std::max(az, bz));
}

// The ray in a YawBox's own frame.
inline Ray box_frame(const Primitive& p, const YawCache& yc, const Ray& r) {
  const Eigen::Vector3f rel = r.o - p.centre;
  const Eigen::Vector3f o(yc.c * rel.x() + yc.s * rel.y(), -yc.s * rel.x() + yc.c * rel.y(), rel.z());
  const Eigen::Vector3f d(yc.c * r.d.x() + yc.s * r.d.y(), -yc.s * r.d.x() + yc.c * r.d.y(), r.d.z());
  return make_ray(o, d);
}

// Side of a cylinder (near root) or the inside of a tube (far root) about axis A.
template <int A>
inline float cylinder_distance(const Primitive& p, const Ray& r) {
  constexpr int i = (A + 1) % 3, j = (A + 2) % 3;
  const float ox = r.o[i] - p.centre[i], oy = r.o[j] - p.centre[j];
  const float dx = r.d[i], dy = r.d[j];
  const float A2 = dx * dx + dy * dy;
  const float B = ox * dx + oy * dy;
  const float C = ox * ox + oy * oy - p.radius * p.radius;
  const float disc = B * B - A2 * C;
  const float root = std::sqrt(std::max(disc, 0.0f));
  const float t = (p.shape == Shape::Cylinder ? -B - root : -B + root) / std::max(A2, 1e-12f);
  const float along = r.o[A] + t * r.d[A];
  const bool ok = disc >= 0.0f && A2 > 1e-12f && t > kEpsilon && along >= p.lo[A] && along <= p.hi[A];
  return ok ? t : kInfinity;
}

// Distance to the primitive's visible surface along the ray, +inf when missed (or not beyond
// kEpsilon). The face is found afterwards, for the nearest hit only (hit_face).
inline float hit_distance(const Primitive& p, const YawCache& yc, const Ray& r) {
  switch (p.shape) {
    case Shape::Box: {
      float tn, tf;
      slab(p.lo, p.hi, r.o, r.inv, tn, tf);
      return (tn <= tf && tn > kEpsilon) ? tn : kInfinity;
    }
    case Shape::RoomBox: {
      float tn, tf;
      slab(p.lo, p.hi, r.o, r.inv, tn, tf);
      return (tn <= tf && tf > kEpsilon) ? tf : kInfinity;
    }
    case Shape::YawBox: {
      const Ray local = box_frame(p, yc, r);
      float tn, tf;
      slab(-p.half, p.half, local.o, local.inv, tn, tf);
      return (tn <= tf && tn > kEpsilon) ? tn : kInfinity;
    }
    case Shape::Cylinder:
    case Shape::Tube:
      switch (p.axis) {
        case 0: return cylinder_distance<0>(p, r);
        case 1: return cylinder_distance<1>(p, r);
        default: return cylinder_distance<2>(p, r);
      }
    case Shape::GroundPlane: {
      const float t = (p.centre.z() - r.o.z()) / r.d.z();
      return (r.d.z() < 0.0f && r.o.z() > p.centre.z() && t > kEpsilon) ? t : kInfinity;
    }
  }
  return kInfinity;
}

// Face index of a hit found by hit_distance: axis * 2 + (1 if the face normal points along +axis)
// for boxes and planes, kCurvedFace for cylinders and tubes.
inline int hit_face(const Primitive& p, const YawCache& yc, const Ray& r) {
  auto box_face = [](const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, const Ray& ray, bool exit) {
    Eigen::Vector3f tn, tf;
    for (int a = 0; a < 3; ++a) {
      const float t0 = (lo[a] - ray.o[a]) * ray.inv[a], t1 = (hi[a] - ray.o[a]) * ray.inv[a];
      tn[a] = std::min(t0, t1);
      tf[a] = std::max(t0, t1);
    }
    int axis = 0;
    if (exit)
      tf.minCoeff(&axis);
    else
      tn.maxCoeff(&axis);
    // Entering a solid box along +d hits the face whose outward normal is -axis; leaving a room
    // along +d hits the wall whose inward normal is -axis: the same rule.
    return axis * 2 + (ray.d[axis] < 0.0f ? 1 : 0);
  };
  switch (p.shape) {
    case Shape::Box: return box_face(p.lo, p.hi, r, false);
    case Shape::RoomBox: return box_face(p.lo, p.hi, r, true);
    case Shape::YawBox: return box_face(-p.half, p.half, box_frame(p, yc, r), false);
    case Shape::Cylinder:
    case Shape::Tube: return kCurvedFace;
    case Shape::GroundPlane: return 2 * 2 + 1;
  }
  return 0;
}

// The same from the hit point x (no division): the box face nearest to x.
inline int hit_face_at(const Primitive& p, const YawCache& yc, const Eigen::Vector3f& x) {
  auto nearest_face = [](const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, const Eigen::Vector3f& q, bool inside) {
    int best = 0;
    float best_d = std::numeric_limits<float>::infinity();
    for (int a = 0; a < 3; ++a) {
      const float dl = std::fabs(q[a] - lo[a]), dh = std::fabs(q[a] - hi[a]);
      // Solid box: the lo face's normal is -axis (0), the hi face's +axis (1); inside a room the
      // normals point inwards: lo face +axis (1), hi face -axis (0).
      if (dl < best_d) { best_d = dl; best = a * 2 + (inside ? 1 : 0); }
      if (dh < best_d) { best_d = dh; best = a * 2 + (inside ? 0 : 1); }
    }
    return best;
  };
  switch (p.shape) {
    case Shape::Box: return nearest_face(p.lo, p.hi, x, false);
    case Shape::RoomBox: return nearest_face(p.lo, p.hi, x, true);
    case Shape::YawBox: {
      const Eigen::Vector3f rel = x - p.centre;
      const Eigen::Vector3f q(yc.c * rel.x() + yc.s * rel.y(), -yc.s * rel.x() + yc.c * rel.y(), rel.z());
      return nearest_face(-p.half, p.half, q, false);
    }
    case Shape::Cylinder:
    case Shape::Tube: return kCurvedFace;
    case Shape::GroundPlane: return 2 * 2 + 1;
  }
  return 0;
}

// Nearest hit of one primitive in (kEpsilon, t_best); updates t_best and face on a hit.
inline bool intersect(const Primitive& p, const YawCache& yc, const Ray& r, float& t_best, int& face) {
  const float t = hit_distance(p, yc, r);
  if (!(t < t_best)) return false;
  t_best = t;
  face = hit_face(p, yc, r);
  return true;
}

// ---------------------------------------------------------------------------------------------
// Packets: four rays from one origin (a pixel's subsamples) tested together with SSE, so the
// candidate loop, its dispatch and the primitive's data are shared by the four.

using Array4f = Eigen::Array4f;

struct Packet {
  Eigen::Vector3f o;         // common origin
  Array4f dx, dy, dz;        // directions
  Array4f ix, iy, iz;        // 1 / direction

  const Array4f& d(int a) const { return a == 0 ? dx : (a == 1 ? dy : dz); }
};

inline Packet make_packet(const Eigen::Vector3f& o, const Array4f& dx, const Array4f& dy, const Array4f& dz) {
  return {o, dx, dy, dz, dx.inverse(), dy.inverse(), dz.inverse()};
}

inline void slab4(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, const Eigen::Vector3f& o, const Array4f& ix,
                  const Array4f& iy, const Array4f& iz, Array4f& t_near, Array4f& t_far) {
  const Array4f ax = (lo.x() - o.x()) * ix, bx = (hi.x() - o.x()) * ix;
  const Array4f ay = (lo.y() - o.y()) * iy, by = (hi.y() - o.y()) * iy;
  const Array4f az = (lo.z() - o.z()) * iz, bz = (hi.z() - o.z()) * iz;
  t_near = ax.min(bx).max(ay.min(by)).max(az.min(bz));
  t_far = ax.max(bx).min(ay.max(by)).min(az.max(bz));
}

template <int A>
inline Array4f cylinder_distance4(const Primitive& p, const Packet& r) {
  constexpr int i = (A + 1) % 3, j = (A + 2) % 3;
  const float ox = r.o[i] - p.centre[i], oy = r.o[j] - p.centre[j];
  const Array4f& dx = r.d(i);
  const Array4f& dy = r.d(j);
  const Array4f A2 = dx * dx + dy * dy;
  const Array4f B = ox * dx + oy * dy;
  const float C = ox * ox + oy * oy - p.radius * p.radius;
  const Array4f disc = B * B - A2 * C;
  const Array4f root = disc.max(0.0f).sqrt();
  const Array4f t = (p.shape == Shape::Cylinder ? Array4f(-B - root) : Array4f(-B + root)) / A2.max(1e-12f);
  const Array4f along = r.o[A] + t * r.d(A);
  const auto ok = (disc >= 0.0f) && (A2 > 1e-12f) && (t > kEpsilon) && (along >= p.lo[A]) && (along <= p.hi[A]);
  return ok.select(t, Array4f::Constant(kInfinity));
}

inline Array4f hit_distance4(const Primitive& p, const YawCache& yc, const Packet& r) {
  const Array4f inf = Array4f::Constant(kInfinity);
  switch (p.shape) {
    case Shape::Box: {
      Array4f tn, tf;
      slab4(p.lo, p.hi, r.o, r.ix, r.iy, r.iz, tn, tf);
      return ((tn <= tf) && (tn > kEpsilon)).select(tn, inf);
    }
    case Shape::RoomBox: {
      Array4f tn, tf;
      slab4(p.lo, p.hi, r.o, r.ix, r.iy, r.iz, tn, tf);
      return ((tn <= tf) && (tf > kEpsilon)).select(tf, inf);
    }
    case Shape::YawBox: {
      const Eigen::Vector3f rel = r.o - p.centre;
      const Eigen::Vector3f o(yc.c * rel.x() + yc.s * rel.y(), -yc.s * rel.x() + yc.c * rel.y(), rel.z());
      const Array4f dx = yc.c * r.dx + yc.s * r.dy, dy = -yc.s * r.dx + yc.c * r.dy;
      Array4f tn, tf;
      slab4(-p.half, p.half, o, dx.inverse(), dy.inverse(), r.iz, tn, tf);
      return ((tn <= tf) && (tn > kEpsilon)).select(tn, inf);
    }
    case Shape::Cylinder:
    case Shape::Tube:
      switch (p.axis) {
        case 0: return cylinder_distance4<0>(p, r);
        case 1: return cylinder_distance4<1>(p, r);
        default: return cylinder_distance4<2>(p, r);
      }
    case Shape::GroundPlane: {
      const float h = p.centre.z() - r.o.z();
      if (h >= 0.0f) return inf;  // seen from below
      const Array4f t = h * r.iz;
      return ((r.dz < 0.0f) && (t > kEpsilon)).select(t, inf);
    }
  }
  return inf;
}

// Geometry at a hit: unit normal (facing the viewer's side), surface coordinates, material.
struct Surface {
  Eigen::Vector3f normal;
  float u = 0.0f, v = 0.0f;
  Material material = Material::Concrete;
};

// Fast atan2 (max error ~1e-5 rad), continuous.
inline float fast_atan2(float y, float x) {
  const float ax = std::fabs(x), ay = std::fabs(y);
  const float mx = std::max(ax, ay), mn = std::min(ax, ay);
  if (mx == 0.0f) return 0.0f;
  const float a = mn / mx;
  const float s = a * a;
  float r = ((-0.0464964749f * s + 0.15931422f) * s - 0.327622764f) * s * a + a;
  if (ay > ax) r = 1.57079637f - r;
  if (x < 0.0f) r = 3.14159274f - r;
  if (y < 0.0f) r = -r;
  return r;
}

inline Surface surface_at(const Primitive& p, const YawCache& yc, int face, const Eigen::Vector3f& x) {
  Surface s;
  if (face == kCurvedFace) {
    const int a = p.axis, i = (a + 1) % 3, j = (a + 2) % 3;
    Eigen::Vector3f radial = Eigen::Vector3f::Zero();
    radial[i] = x[i] - p.centre[i];
    radial[j] = x[j] - p.centre[j];
    const float len = std::sqrt(radial[i] * radial[i] + radial[j] * radial[j]);
    radial /= std::max(len, 1e-6f);
    s.normal = p.shape == Shape::Tube ? Eigen::Vector3f(-radial) : radial;
    // u: arc length, from +x round a vertical cylinder, from the bottom round a horizontal one.
    float angle = 0.0f;
    if (a == 2)
      angle = fast_atan2(radial.y(), radial.x());
    else
      angle = fast_atan2(radial[a == 0 ? 1 : 0], -radial.z());
    s.u = angle * p.radius;
    s.v = x[a];
    s.material = p.side;
    return s;
  }
  const int axis = face / 2;
  const float sign = (face % 2) ? 1.0f : -1.0f;  // face%2 == 1: normal +axis
  Eigen::Vector3f n = Eigen::Vector3f::Zero();
  n[axis] = sign;
  Eigen::Vector3f local = x;
  if (p.shape == Shape::YawBox) {
    const Eigen::Vector3f rel = x - p.centre;
    local = Eigen::Vector3f(yc.c * rel.x() + yc.s * rel.y(), -yc.s * rel.x() + yc.c * rel.y(), rel.z());
    n = Eigen::Vector3f(yc.c * n.x() - yc.s * n.y(), yc.s * n.x() + yc.c * n.y(), n.z());
  }
  s.normal = n;
  if (axis == 0) {
    s.u = local.y();
    s.v = local.z();
  } else if (axis == 1) {
    s.u = local.x();
    s.v = local.z();
  } else {
    s.u = local.x();
    s.v = local.y();
  }
  s.material = axis != 2 ? p.side : (sign > 0.0f ? p.top : p.bottom);
  return s;
}

}  // namespace nirslam::sim::detail
