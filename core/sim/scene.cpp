#include "nirslam/sim/scene.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <stdexcept>
#include <string>

#include "kernels.hpp"
#include "layout.hpp"
#include "nirslam/common/text_fields.hpp"
#include "nirslam/sim/texture.hpp"

namespace nirslam::sim {

namespace {

using Eigen::Vector3f;

// A small deterministic generator (splitmix64): the same scene on every platform and library.
class Rng {
public:
  explicit Rng(std::uint64_t seed) : state_(seed * 0x9E3779B97F4A7C15ull + 0x632BE59BD9B4E019ull) {}
  std::uint64_t next() {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  float uniform(float lo, float hi) {
    return lo + (hi - lo) * static_cast<float>(next() >> 40) * (1.0f / 16777216.0f);
  }
  bool chance(float p) { return uniform(0.0f, 1.0f) < p; }
  std::uint32_t seed() { return static_cast<std::uint32_t>(next() >> 32); }

private:
  std::uint64_t state_;
};

class Builder {
public:
  explicit Builder(std::uint32_t seed) : rng(seed) {}

  Primitive& box(const Vector3f& lo, const Vector3f& hi, Material side, Material top, Material bottom) {
    Primitive p;
    p.shape = Shape::Box;
    p.lo = lo.cwiseMin(hi);
    p.hi = lo.cwiseMax(hi);
    p.side = side;
    p.top = top;
    p.bottom = bottom;
    return add(p);
  }
  Primitive& box(const Vector3f& lo, const Vector3f& hi, Material all) { return box(lo, hi, all, all, all); }

  Primitive& yaw_box(const Vector3f& centre, const Vector3f& half, float yaw, Material side, Material top) {
    Primitive p;
    p.shape = Shape::YawBox;
    p.centre = centre;
    p.half = half;
    p.yaw = yaw;
    p.side = side;
    p.top = top;
    p.bottom = side;
    return add(p);
  }

  Primitive& room(const Vector3f& lo, const Vector3f& hi, Material walls, Material floor, Material ceiling) {
    Primitive p;
    p.shape = Shape::RoomBox;
    p.lo = lo;
    p.hi = hi;
    p.side = walls;
    p.top = floor;  // the floor's normal points up, into the room
    p.bottom = ceiling;
    return add(p);
  }

  // A cylinder (or the inside of one) along `axis` through (centre), over [from, to] on the axis.
  Primitive& cylinder(Shape shape, int axis, const Vector3f& centre, float radius, float from, float to,
                      Material material) {
    Primitive p;
    p.shape = shape;
    p.axis = axis;
    p.centre = centre;
    p.radius = radius;
    p.lo = centre;
    p.hi = centre;
    p.lo[axis] = std::min(from, to);
    p.hi[axis] = std::max(from, to);
    p.side = p.top = p.bottom = material;
    return add(p);
  }

  // A cylinder along x split into pieces of at most `piece` metres, so culling can drop the far ones.
  void cylinder_x(float y, float z, float radius, float from, float to, float piece, Material material) {
    const int n = std::max(1, static_cast<int>(std::ceil((to - from) / piece)));
    const std::uint32_t s = rng.seed();
    for (int i = 0; i < n; ++i) {
      const float a = from + (to - from) * static_cast<float>(i) / static_cast<float>(n);
      const float b = from + (to - from) * static_cast<float>(i + 1) / static_cast<float>(n);
      cylinder(Shape::Cylinder, 0, Vector3f(0.0f, y, z), radius, a, b, material).seed = s;
    }
  }

  Primitive& ground(float z, Material material) {
    Primitive p;
    p.shape = Shape::GroundPlane;
    p.centre = Vector3f(0.0f, 0.0f, z);
    p.side = p.top = p.bottom = material;
    return add(p);
  }

  // A parked car: body and a narrower cabin; `along_x` says which way it is parked.
  void car(float cx, float cy, bool along_x) {
    const float half_length = rng.uniform(2.1f, 2.4f), half_width = rng.uniform(0.85f, 0.95f);
    const float hl = along_x ? half_length : half_width, hw = along_x ? half_width : half_length;
    const std::uint32_t paint = rng.seed();
    begin_group();
    const float body_top = rng.uniform(0.85f, 1.0f), roof = body_top + rng.uniform(0.42f, 0.55f);
    box({cx - hl, cy - hw, 0.12f}, {cx + hl, cy + hw, body_top}, Material::CarBody, Material::CarBody,
        Material::Rubber).seed = paint;
    const float inset_front = 0.45f * half_length, inset_back = 0.3f * half_length;
    const float ax = along_x ? inset_front : 0.08f, bx = along_x ? inset_back : 0.08f;
    const float ay = along_x ? 0.08f : inset_front, by = along_x ? 0.08f : inset_back;
    Primitive& cabin = box({cx - hl + ax, cy - hw + ay, body_top}, {cx + hl - bx, cy + hw - by, roof},
                           Material::CarWindow, Material::CarBody, Material::CarBody);
    cabin.seed = paint;
    end_group();
  }

  Scene finish(SceneKind kind, std::uint32_t seed) {
    // Order: unbounded primitives, then each group's members together, then the rest.
    std::vector<int> group_of(primitives.size(), -1);
    for (std::size_t g = 0; g < group_ranges_.size(); ++g)
      for (int i = 0; i < group_ranges_[g].count; ++i)
        group_of[static_cast<std::size_t>(group_ranges_[g].first + i)] = static_cast<int>(g);
    Scene scene;
    scene.kind = kind;
    scene.seed = seed;
    for (const Primitive& p : primitives)
      if (p.unbounded()) scene.primitives.push_back(p);
    for (const Range& range : group_ranges_) {
      PrimitiveGroup group;
      group.first = static_cast<int>(scene.primitives.size());
      group.count = range.count;
      group.lo = Vector3f::Constant(std::numeric_limits<float>::infinity());
      group.hi = -group.lo;
      for (int i = 0; i < range.count; ++i) {
        const Primitive& p = primitives[static_cast<std::size_t>(range.first + i)];
        Vector3f lo, hi;
        p.bounds(lo, hi);
        group.lo = group.lo.cwiseMin(lo);
        group.hi = group.hi.cwiseMax(hi);
        scene.primitives.push_back(p);
      }
      scene.groups.push_back(group);
    }
    // Long thin boxes (trays, beams) outside groups become pieces of at most kPiece metres:
    // their bounding spheres then fit, and the renderer's culling keeps them out of the tiles
    // that cannot see them. The union is the same box and the textures use world coordinates,
    // so it looks the same.
    constexpr float kPiece = 3.0f;
    for (std::size_t k = 0; k < primitives.size(); ++k) {
      const Primitive& p = primitives[k];
      if (p.unbounded() || group_of[k] >= 0) continue;
      if (p.shape != Shape::Box) {
        scene.primitives.push_back(p);
        continue;
      }
      const Vector3f size = p.hi - p.lo;
      int axis = 0;
      size.maxCoeff(&axis);
      Vector3f sorted = size;
      std::sort(sorted.data(), sorted.data() + 3);
      if (size[axis] <= kPiece || sorted[2] < 3.0f * sorted[1]) {
        scene.primitives.push_back(p);
        continue;
      }
      const int n = static_cast<int>(std::ceil(size[axis] / kPiece));
      for (int i = 0; i < n; ++i) {
        Primitive piece = p;
        piece.lo[axis] = p.lo[axis] + size[axis] * static_cast<float>(i) / static_cast<float>(n);
        piece.hi[axis] = i + 1 == n ? p.hi[axis] : p.lo[axis] + size[axis] * static_cast<float>(i + 1) / static_cast<float>(n);
        scene.primitives.push_back(piece);
      }
    }
    return scene;
  }

  void begin_group() { group_start_ = static_cast<int>(primitives.size()); }
  void end_group() {
    if (group_start_ >= 0 && static_cast<int>(primitives.size()) - group_start_ > 1)
      group_ranges_.push_back({group_start_, static_cast<int>(primitives.size()) - group_start_});
    group_start_ = -1;
  }

  Rng rng;
  std::vector<Primitive> primitives;

private:
  struct Range {
    int first, count;
  };
  int group_start_ = -1;
  std::vector<Range> group_ranges_;

  Primitive& add(Primitive p) {
    p.seed = rng.seed();
    primitives.push_back(p);
    return primitives.back();
  }
};

// ---------------------------------------------------------------------------------------------

Scene make_room(std::uint32_t seed) {
  using namespace layout;
  Builder b(seed);
  b.room({-kRoomHalfX, -kRoomHalfY, 0.0f}, {kRoomHalfX, kRoomHalfY, kRoomHeight}, Material::PaintedWall,
         (seed & 1u) ? Material::FloorTiles : Material::WoodFloor, Material::CeilingTiles);
  // North wall: two bookshelves and a low cabinet with boxes on it.
  b.box({-3.7f, 2.62f, 0.0f}, {-1.6f, 3.0f, 2.0f}, Material::Bookshelf, Material::Cabinet, Material::Cabinet);
  b.box({-1.4f, 2.62f, 0.0f}, {0.2f, 3.0f, 1.75f}, Material::Bookshelf, Material::Cabinet, Material::Cabinet);
  b.box({0.6f, 2.5f, 0.0f}, {2.4f, 3.0f, 0.85f}, Material::Cabinet, Material::TableTop, Material::Cabinet);
  for (int i = 0; i < 3; ++i) {
    const float x = 0.75f + 0.55f * static_cast<float>(i) + b.rng.uniform(0.0f, 0.1f);
    const float s = b.rng.uniform(0.12f, 0.22f);
    b.yaw_box({x, 2.75f, 0.85f + s}, {s, s, s}, b.rng.uniform(-0.3f, 0.3f), Material::Cabinet, Material::Cabinet);
  }
  // South wall: cabinets and a tall cupboard.
  b.box({-3.6f, -3.0f, 0.0f}, {-0.6f, -2.45f, 0.9f}, Material::Cabinet, Material::TableTop, Material::Cabinet);
  b.box({0.4f, -3.0f, 0.0f}, {1.5f, -2.4f, 2.1f}, Material::Cabinet, Material::Cabinet, Material::Cabinet);
  b.box({1.9f, -3.0f, 0.0f}, {3.4f, -2.65f, 1.6f}, Material::Bookshelf, Material::Cabinet, Material::Cabinet);
  // West wall: a sofa.
  b.box({-3.95f, -1.2f, 0.0f}, {-3.1f, 1.2f, 0.45f}, Material::Fabric);
  b.box({-4.0f, -1.2f, 0.0f}, {-3.72f, 1.2f, 0.88f}, Material::Fabric);
  b.box({-4.0f, -1.45f, 0.0f}, {-3.1f, -1.2f, 0.62f}, Material::Fabric);
  b.box({-4.0f, 1.2f, 0.0f}, {-3.1f, 1.45f, 0.62f}, Material::Fabric);
  // East wall: a desk with drawers and a monitor.
  b.box({3.2f, -1.0f, 0.72f}, {3.95f, 1.0f, 0.76f}, Material::Cabinet, Material::TableTop, Material::Cabinet);
  b.box({3.2f, 0.45f, 0.0f}, {3.95f, 1.0f, 0.72f}, Material::Cabinet);
  b.yaw_box({3.7f, 0.0f, 1.0f}, {0.025f, 0.32f, 0.2f}, b.rng.uniform(-0.15f, 0.15f), Material::Rubber, Material::Rubber);
  b.box({3.66f, -0.05f, 0.76f}, {3.74f, 0.05f, 0.8f}, Material::Metal);
  // The table in the middle, turned a little.
  b.yaw_box({0.0f, 0.0f, 0.38f}, {0.7f, 0.45f, 0.38f}, b.rng.uniform(0.15f, 0.5f), Material::Cabinet, Material::TableTop);
  // Crates in the north-east and south-west corners.
  for (int i = 0; i < 4; ++i) {
    const float s = b.rng.uniform(0.18f, 0.3f);
    const float x = 3.0f + b.rng.uniform(0.0f, 0.55f), y = 1.95f + b.rng.uniform(0.0f, 0.55f);
    const float z = i < 3 ? s : 2.0f * 0.3f + s;
    b.yaw_box({x, y, z}, {s, s, s}, b.rng.uniform(-0.4f, 0.4f), Material::Cabinet, Material::Cabinet);
  }
  b.yaw_box({-3.5f, -2.3f, 0.3f}, {0.3f, 0.3f, 0.3f}, b.rng.uniform(-0.4f, 0.4f), Material::Metal, Material::Metal);
  Scene scene = b.finish(SceneKind::Room, seed);
  scene.sky_radiance = 0.0;
  scene.typical_ambient_irradiance = 0.002;  // a little light through the windows at night
  scene.min_clearance_m = 0.3;
  return scene;
}

Scene make_outdoor(std::uint32_t seed) {
  using namespace layout;
  Builder b(seed);
  b.ground(0.0f, Material::Street);
  auto facade = [&](bool brick) { return brick ? Material::Brick : Material::Plaster; };
  // The block in the middle: two buildings.
  b.box({-kBlockHalfX, -kBlockHalfY, 0.0f}, {-1.0f, kBlockHalfY, 12.0f}, Material::Brick, Material::Concrete, Material::Concrete);
  b.box({-1.0f, -kBlockHalfY, 0.0f}, {kBlockHalfX, kBlockHalfY, 15.0f}, Material::Plaster, Material::Concrete, Material::Concrete);
  // The outer buildings, with alleys between them.
  const float north = kBlockHalfY + kOuterFacade, east = kBlockHalfX + kOuterFacade;
  for (const float sign : {1.0f, -1.0f}) {
    const float xs[][2] = {{-36.0f, -14.0f}, {-11.0f, 6.0f}, {9.0f, 36.0f}};
    for (const auto& x : xs)
      b.box({x[0], sign * north, 0.0f}, {x[1], sign * (north + 14.0f), b.rng.uniform(8.0f, 20.0f)},
            facade(b.rng.chance(0.5f)), Material::Concrete, Material::Concrete);
    const float ys[][2] = {{-16.0f, -2.0f}, {2.0f, 16.0f}};
    for (const auto& y : ys)
      b.box({sign * east, y[0], 0.0f}, {sign * (east + 14.0f), y[1], b.rng.uniform(8.0f, 20.0f)},
            facade(b.rng.chance(0.5f)), Material::Concrete, Material::Concrete);
  }
  // Hedges and lamp posts on the inner pavement.
  for (const float sign : {1.0f, -1.0f}) {
    for (const float x0 : {-12.0f, 1.0f, 9.0f})
      if (b.rng.chance(0.75f))
        b.box({x0, sign * (kBlockHalfY + 0.2f), 0.0f}, {x0 + b.rng.uniform(3.0f, 5.0f), sign * (kBlockHalfY + 1.0f), b.rng.uniform(0.7f, 1.1f)},
              Material::Vegetation);
    b.box({sign * (kBlockHalfX + 0.2f), -4.0f, 0.0f}, {sign * (kBlockHalfX + 0.9f), 1.0f, 0.9f}, Material::Vegetation);
    for (const float x : {-12.0f, 0.0f, 12.0f}) {
      const float y = sign * (kBlockHalfY + 1.1f);
      b.cylinder(Shape::Cylinder, 2, {x, y, 0.0f}, 0.08f, 0.0f, 5.0f, Material::Metal);
      b.box({x - 0.3f, y - 0.12f, 5.0f}, {x + 0.3f, y + 0.12f, 5.15f}, Material::Lamp);
    }
    for (const float y : {-5.0f, 5.0f})
      b.cylinder(Shape::Cylinder, 2, {sign * (kBlockHalfX + 1.1f), y, 0.0f}, 0.08f, 0.0f, 5.0f, Material::Metal);
  }
  // Cars parked along the outer kerb.
  const float lane = 0.5f * (6.6f + 8.4f);
  for (const float sign : {1.0f, -1.0f}) {
    for (float x = -18.0f; x <= 18.0f; x += 5.5f)
      if (b.rng.chance(0.55f)) b.car(x, sign * (kBlockHalfY + lane), true);
    for (float y = -4.5f; y <= 4.5f; y += 5.5f)
      if (b.rng.chance(0.55f)) b.car(sign * (kBlockHalfX + lane), y, false);
  }
  Scene scene = b.finish(SceneKind::Outdoor, seed);
  scene.sky_radiance = 0.002;              // dusk sky at 850 nm: almost nothing comes back
  scene.typical_ambient_irradiance = 0.015;  // skylight at dusk: far facades stay faintly visible
  scene.min_clearance_m = 0.4;
  return scene;
}

Scene make_parking(std::uint32_t seed) {
  using namespace layout;
  Builder b(seed);
  b.room({-kParkHalfX, -kParkHalfY, 0.0f}, {kParkHalfX, kParkHalfY, kParkHeight}, Material::Concrete,
         Material::ParkingFloor, Material::Concrete);
  for (const float y : {-kOuterRowY, 0.0f, kOuterRowY})
    for (float x = -2.0f * kPillarSpacing; x <= 2.0f * kPillarSpacing + 0.1f; x += kPillarSpacing)
      b.box({x - kPillarHalf, y - kPillarHalf, 0.0f}, {x + kPillarHalf, y + kPillarHalf, kParkHeight}, Material::Pillar,
            Material::Concrete, Material::Concrete);
  for (float x = -3.0f * kPillarSpacing; x <= 3.0f * kPillarSpacing + 0.1f; x += kPillarSpacing)
    b.box({x - 0.25f, -kParkHalfY, 2.25f}, {x + 0.25f, kParkHalfY, kParkHeight}, Material::Concrete);
  for (const float y : {-3.2f, 3.2f}) b.cylinder_x(y, 2.45f, 0.15f, -kParkHalfX, kParkHalfX, 2.5f, Material::PipeSteel);
  b.cylinder_x(-9.5f, 2.5f, 0.08f, -kParkHalfX, kParkHalfX, 2.5f, Material::PipeSteel);
  for (const float y : {-static_cast<float>(kAisleY), static_cast<float>(kAisleY)})
    for (float x = -28.0f; x <= 28.1f; x += kPillarSpacing)
      b.box({x - 0.6f, y - 0.08f, 2.52f}, {x + 0.6f, y + 0.08f, 2.6f}, Material::Lamp);
  // Cars in the bays.
  for (int j = -8; j < 8; ++j) {
    const float x = kBayWidth * (static_cast<float>(j) + 0.5f);
    const float rows[][2] = {{kCarRowInner, kCarRowOuter}, {-kCarRowOuter, -kCarRowInner},
                             {kOuterCarsFrom, kOuterCarsTo}, {-kOuterCarsTo, -kOuterCarsFrom}};
    for (const auto& row : rows)
      if (b.rng.chance(0.65f)) b.car(x, 0.5f * (row[0] + row[1]), false);
  }
  Scene scene = b.finish(SceneKind::Parking, seed);
  scene.sky_radiance = 0.0;
  scene.typical_ambient_irradiance = 0.001;
  scene.glossy_floor = GlossyFloor{0.0f, 0.04f, 0.6f};
  scene.min_clearance_m = 0.35;  // the robot's camera rides 0.45 m above the floor
  return scene;
}

Scene make_tunnel(std::uint32_t seed) {
  using namespace layout;
  Builder b(seed);
  b.cylinder(Shape::Tube, 0, {0.0f, 0.0f, kTubeAxisZ}, kTubeRadius, -kTubeHalfLength, kTubeHalfLength,
             Material::TunnelLining);
  b.ground(kWalkwayZ, Material::Concrete);
  for (const float sign : {1.0f, -1.0f})
    b.box({sign * kTubeHalfLength, -2.0f, 0.0f}, {sign * (kTubeHalfLength + 0.5f), 2.0f, 3.7f}, Material::Concrete);
  // Cable trays on the right, on brackets every 2 m, two cables on each; each 2.5 m of a tray
  // with its cables is one group.
  constexpr float kPieceLength = 2.5f;
  const int pieces = static_cast<int>(2.0f * kTubeHalfLength / kPieceLength);
  for (const float z : {1.0f, 1.45f, 1.9f}) {
    const std::uint32_t tray = b.rng.seed(), cable_a = b.rng.seed(), cable_b = b.rng.seed();
    for (int i = 0; i < pieces; ++i) {
      const float x0 = -kTubeHalfLength + kPieceLength * static_cast<float>(i), x1 = x0 + kPieceLength;
      b.begin_group();
      b.box({x0, 0.95f, z}, {x1, 1.45f, z + 0.03f}, Material::Metal).seed = tray;
      b.cylinder(Shape::Cylinder, 0, {0.0f, 1.08f, z + 0.06f}, 0.03f, x0, x1, Material::Rubber).seed = cable_a;
      b.cylinder(Shape::Cylinder, 0, {0.0f, 1.27f, z + 0.075f}, 0.045f, x0, x1, Material::Rubber).seed = cable_b;
      b.end_group();
    }
  }
  for (float x = -kTubeHalfLength + 1.0f; x < kTubeHalfLength; x += 2.0f)
    b.box({x - 0.03f, 1.45f, 0.85f}, {x + 0.03f, 1.52f, 2.7f}, Material::Metal);
  // Pipes on the left, on supports every 3 m; each 2.5 m of the two pipes is one group.
  const std::uint32_t pipe_a = b.rng.seed(), pipe_b = b.rng.seed();
  for (int i = 0; i < pieces; ++i) {
    const float x0 = -kTubeHalfLength + kPieceLength * static_cast<float>(i), x1 = x0 + kPieceLength;
    b.begin_group();
    b.cylinder(Shape::Cylinder, 0, {0.0f, -1.05f, 0.75f}, 0.2f, x0, x1, Material::PipeSteel).seed = pipe_a;
    b.cylinder(Shape::Cylinder, 0, {0.0f, -1.3f, 1.45f}, 0.1f, x0, x1, Material::PipeSteel).seed = pipe_b;
    b.end_group();
  }
  for (float x = -kTubeHalfLength + 1.5f; x < kTubeHalfLength; x += 3.0f)
    b.box({x - 0.08f, -1.2f, kWalkwayZ}, {x + 0.08f, -0.9f, 0.56f}, Material::Metal);
  // Lamps in the crown every 6 m (switched off: the illuminator is the only light).
  for (float x = -kTubeHalfLength + 3.0f; x < kTubeHalfLength; x += 6.0f)
    b.box({x - 0.6f, -0.12f, 3.42f}, {x + 0.6f, 0.12f, 3.52f}, Material::Lamp);
  Scene scene = b.finish(SceneKind::Tunnel, seed);
  scene.sky_radiance = 0.0;
  scene.typical_ambient_irradiance = 0.0005;
  scene.min_clearance_m = 0.25;
  return scene;
}

}  // namespace

std::string_view to_string(SceneKind kind) {
  switch (kind) {
    case SceneKind::Room: return "room";
    case SceneKind::Outdoor: return "outdoor";
    case SceneKind::Parking: return "parking";
    case SceneKind::Tunnel: return "tunnel";
  }
  return "unknown";
}

std::optional<SceneKind> parse_scene_kind(std::string_view name) {
  const std::string key = lowercase(name);
  if (key == "room" || key == "indoor") return SceneKind::Room;
  if (key == "outdoor") return SceneKind::Outdoor;
  if (key == "parking" || key == "underground") return SceneKind::Parking;
  if (key == "tunnel" || key == "pipe") return SceneKind::Tunnel;
  return std::nullopt;
}

std::string_view to_string(Material material) {
  switch (material) {
    case Material::PaintedWall: return "painted_wall";
    case Material::Concrete: return "concrete";
    case Material::TunnelLining: return "tunnel_lining";
    case Material::FloorTiles: return "floor_tiles";
    case Material::WoodFloor: return "wood_floor";
    case Material::CeilingTiles: return "ceiling_tiles";
    case Material::Bookshelf: return "bookshelf";
    case Material::Cabinet: return "cabinet";
    case Material::Fabric: return "fabric";
    case Material::TableTop: return "table_top";
    case Material::Brick: return "brick";
    case Material::Plaster: return "plaster";
    case Material::Street: return "street";
    case Material::Vegetation: return "vegetation";
    case Material::ParkingFloor: return "parking_floor";
    case Material::Pillar: return "pillar";
    case Material::CarBody: return "car_body";
    case Material::CarWindow: return "car_window";
    case Material::Metal: return "metal";
    case Material::Rubber: return "rubber";
    case Material::PipeSteel: return "pipe_steel";
    case Material::Lamp: return "lamp";
  }
  return "unknown";
}

Eigen::Vector3f Primitive::bound_centre() const {
  switch (shape) {
    case Shape::Box: return 0.5f * (lo + hi);
    case Shape::YawBox: return centre;
    case Shape::Cylinder: {
      Eigen::Vector3f c = centre;
      c[axis] = 0.5f * (lo[axis] + hi[axis]);
      return c;
    }
    default: return Eigen::Vector3f::Zero();
  }
}

void Primitive::bounds(Eigen::Vector3f& lo_out, Eigen::Vector3f& hi_out) const {
  switch (shape) {
    case Shape::Box:
      lo_out = lo;
      hi_out = hi;
      return;
    case Shape::YawBox: {
      const float c = std::fabs(std::cos(yaw)), s = std::fabs(std::sin(yaw));
      const Eigen::Vector3f extent(c * half.x() + s * half.y(), s * half.x() + c * half.y(), half.z());
      lo_out = centre - extent;
      hi_out = centre + extent;
      return;
    }
    case Shape::Cylinder:
      lo_out = centre - Eigen::Vector3f::Constant(radius);
      hi_out = centre + Eigen::Vector3f::Constant(radius);
      lo_out[axis] = lo[axis];
      hi_out[axis] = hi[axis];
      return;
    default:
      lo_out = Eigen::Vector3f::Constant(-std::numeric_limits<float>::infinity());
      hi_out = -lo_out;
  }
}

float Primitive::bound_radius() const {
  switch (shape) {
    case Shape::Box: return 0.5f * (hi - lo).norm();
    case Shape::YawBox: return half.norm();
    case Shape::Cylinder: {
      const float half_length = 0.5f * (hi[axis] - lo[axis]);
      return std::sqrt(radius * radius + half_length * half_length);
    }
    default: return std::numeric_limits<float>::infinity();
  }
}

Scene make_scene(SceneKind kind, std::uint32_t seed) {
  switch (kind) {
    case SceneKind::Room: return make_room(seed);
    case SceneKind::Outdoor: return make_outdoor(seed);
    case SceneKind::Parking: return make_parking(seed);
    case SceneKind::Tunnel: return make_tunnel(seed);
  }
  throw std::invalid_argument("unknown scene kind");
}

std::optional<SurfaceHit> cast_ray(const Scene& scene, const Eigen::Vector3d& origin,
                                   const Eigen::Vector3d& direction, double t_max) {
  const double length = direction.norm();
  if (!(length > 0.0)) return std::nullopt;
  const Eigen::Vector3d unit = direction / length;
  const detail::Ray ray = detail::make_ray(origin.cast<float>(), unit.cast<float>());
  float t_best = std::isfinite(t_max) ? static_cast<float>(t_max) : std::numeric_limits<float>::infinity();
  int best = -1, face = 0;
  for (std::size_t i = 0; i < scene.primitives.size(); ++i) {
    const Primitive& p = scene.primitives[i];
    const detail::YawCache yc{std::cos(p.yaw), std::sin(p.yaw)};
    if (detail::intersect(p, yc, ray, t_best, face)) best = static_cast<int>(i);
  }
  if (best < 0) return std::nullopt;
  const Primitive& p = scene.primitives[static_cast<std::size_t>(best)];
  const detail::YawCache yc{std::cos(p.yaw), std::sin(p.yaw)};
  SurfaceHit hit;
  hit.t = t_best;
  hit.point = origin + unit * hit.t;
  const detail::Surface s = detail::surface_at(p, yc, face, hit.point.cast<float>());
  hit.normal = s.normal.cast<double>();
  if (hit.normal.dot(unit) > 0.0) hit.normal = -hit.normal;
  hit.primitive = best;
  hit.material = s.material;
  hit.u = s.u;
  hit.v = s.v;
  return hit;
}

double albedo_at(const Scene& scene, const SurfaceHit& hit, double footprint_m) {
  const Primitive& p = scene.primitives.at(static_cast<std::size_t>(hit.primitive));
  const float a = material_albedo(hit.material, static_cast<float>(hit.u), static_cast<float>(hit.v),
                                  static_cast<float>(footprint_m), p.seed) * p.albedo_scale;
  return std::clamp(static_cast<double>(a), 0.0, 1.0);
}

}  // namespace nirslam::sim
