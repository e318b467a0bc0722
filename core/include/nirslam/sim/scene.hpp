#pragma once

// The simulator's worlds: small lists of analytic primitives with procedural NIR albedo, modelled
// on the four scene types of the NIR-VSLAM paper. World frame: metres, z up.

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

namespace nirslam::sim {

enum class SceneKind {
  Room,     // indoor room: a box with furniture-like blocks (shelves, cabinets, table, sofa)
  Outdoor,  // a street loop around a building block: ground, facades, hedges, poles, open sky
  Parking,  // underground parking: low ceiling with beams, pillar grid, parked cars, glossy floor
  Tunnel,   // pipe tunnel: long concrete tube, walkway, cable trays on brackets, pipes, lamps
};

std::string_view to_string(SceneKind kind);
// "room" (also "indoor"), "outdoor", "parking" (also "underground"), "tunnel" (also "pipe"); any case.
std::optional<SceneKind> parse_scene_kind(std::string_view name);

// Surface materials. Each is an albedo pattern at 850 nm evaluated from surface coordinates (see
// texture.hpp); values are typical NIR reflectances (white paint ~0.8, concrete ~0.35, asphalt
// ~0.12, vegetation ~0.5 (bright in NIR), black rubber ~0.05, window glass at night ~0.03).
enum class Material : std::uint8_t {
  PaintedWall,    // walls with posters, frames, sockets, baseboard
  Concrete,       // cast concrete: formwork joints, tie holes, stains, pits
  TunnelLining,   // segmented concrete tube: ring joints, bolt pockets, water streaks, signs
  FloorTiles,     // ceramic tiles with grout
  WoodFloor,      // staggered planks with grain
  CeilingTiles,   // suspended ceiling: T-bar grid, perforated tiles
  Bookshelf,      // shelf boards with books of random widths and heights
  Cabinet,        // wooden doors with gaps and handles
  Fabric,         // upholstery with seams
  TableTop,       // wood veneer with grain
  Brick,          // brick facade with windows and doors
  Plaster,        // rendered facade with windows
  Street,         // outdoor ground: asphalt, lane markings, kerbs, pavement slabs, grass
  Vegetation,     // hedges: leafy high-contrast noise (bright in NIR)
  ParkingFloor,   // epoxy-coated concrete with bay lines, arrows and tyre marks
  Pillar,         // painted concrete column with hazard stripes and a number
  CarBody,        // car paint with panel seams and door handles
  CarWindow,      // dark glass with door pillars
  Metal,          // galvanised steel (brackets, trays, poles)
  Rubber,         // black cable sheath
  PipeSteel,      // painted pipes with flanges
  Lamp,           // a switched-off lamp housing (bright diffuser, dark frame)
};

std::string_view to_string(Material material);

enum class Shape : std::uint8_t {
  Box,          // solid axis-aligned box [lo, hi]
  YawBox,       // solid box of half extents `half`, centred at `centre`, turned by `yaw` about z
  RoomBox,      // the inside of an axis-aligned box [lo, hi] (a room, a garage), seen from within
  Cylinder,     // solid cylinder, axis along `axis` through `centre`, over [lo[axis], hi[axis]];
                // side surface only (its ends always touch other geometry)
  Tube,         // the inside of such a cylinder (the pipe tunnel), seen from within
  GroundPlane,  // the plane z = centre.z seen from above, unbounded
};

struct Primitive {
  Shape shape = Shape::Box;
  int axis = 2;                                      // Cylinder, Tube
  Eigen::Vector3f lo = Eigen::Vector3f::Zero();      // Box, RoomBox; extent along the axis
  Eigen::Vector3f hi = Eigen::Vector3f::Zero();
  Eigen::Vector3f centre = Eigen::Vector3f::Zero();  // YawBox, Cylinder, Tube, GroundPlane
  Eigen::Vector3f half = Eigen::Vector3f::Zero();    // YawBox
  float radius = 0.0f;                               // Cylinder, Tube
  float yaw = 0.0f;                                  // YawBox, radians
  Material side = Material::Concrete;                // faces whose normal is horizontal, and curved surfaces
  Material top = Material::Concrete;                 // face with normal +z (RoomBox: the floor)
  Material bottom = Material::Concrete;              // face with normal -z (RoomBox: the ceiling)
  float albedo_scale = 1.0f;                         // per-object variation
  std::uint32_t seed = 0;                            // texture variation

  // A sphere holding the primitive (infinite for RoomBox, Tube, GroundPlane: never culled).
  Eigen::Vector3f bound_centre() const;
  float bound_radius() const;
  // An axis-aligned box holding a bounded primitive.
  void bounds(Eigen::Vector3f& lo_out, Eigen::Vector3f& hi_out) const;
  bool unbounded() const { return shape == Shape::RoomBox || shape == Shape::Tube || shape == Shape::GroundPlane; }
};

// A horizontal glossy floor: besides its Lambertian albedo, it mirrors the scene with a Schlick
// Fresnel reflectance R0 + (1 - R0)(1 - cos)^5, scaled by `strength` (a rough coating reflects
// less than a clean mirror).
struct GlossyFloor {
  float z = 0.0f;
  float r0 = 0.04f;       // normal-incidence reflectance of a clear coat (refractive index ~1.5)
  float strength = 0.6f;
};

// Primitives [first, first + count) that lie close together (a cable tray with its cables, a car's
// body and cabin), with a box holding them all: a ray that misses the box skips them all.
struct PrimitiveGroup {
  int first = 0;
  int count = 0;
  Eigen::Vector3f lo = Eigen::Vector3f::Zero(), hi = Eigen::Vector3f::Zero();
};

struct Scene {
  SceneKind kind = SceneKind::Room;
  std::uint32_t seed = 0;
  // Unbounded (enclosing) primitives first, then the members of each group together, then the rest.
  std::vector<Primitive> primitives;
  std::vector<PrimitiveGroup> groups;
  // Radiance of rays that leave the scene (W m^-2 sr^-1 at 850 nm; the night/dusk sky is dark).
  double sky_radiance = 0.0;
  // Typical ambient NIR irradiance (W m^-2) for this scene; the simulator's options may override.
  double typical_ambient_irradiance = 0.0;
  std::optional<GlossyFloor> glossy_floor;
  // Where cameras may go: trajectories keep at least this clearance from every surface.
  double min_clearance_m = 0.25;
};

// The scene of a kind; `seed` varies furniture, cars and texture details but not the layout that
// the trajectories rely on.
Scene make_scene(SceneKind kind, std::uint32_t seed);

// What a ray hit.
struct SurfaceHit {
  double t = 0.0;                 // distance along the (unit) ray direction
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  // unit, facing the ray's origin side
  int primitive = -1;
  Material material = Material::Concrete;
  double u = 0.0, v = 0.0;        // surface coordinates in metres (v up on vertical faces)
};

// The nearest surface along origin + t * direction (direction need not be unit), t in (0, t_max).
// Brute force over all primitives: for tests, trajectory checks and single rays; the renderer
// culls per image tile.
std::optional<SurfaceHit> cast_ray(const Scene& scene, const Eigen::Vector3d& origin,
                                   const Eigen::Vector3d& direction,
                                   double t_max = std::numeric_limits<double>::infinity());

// Albedo (NIR reflectance, 0..1) of a hit, band-limited to a footprint of `footprint_m` metres
// (the size of a pixel on the surface): detail finer than the footprint fades to its mean.
double albedo_at(const Scene& scene, const SurfaceHit& hit, double footprint_m = 0.0);

}  // namespace nirslam::sim
