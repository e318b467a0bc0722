#pragma once

// CPU ray caster for the simulator: scene radiance as a NIR camera with a co-located illuminator
// sees it. No GL; deterministic (every pixel is computed the same way whatever the thread count).
//
// Radiometry (units: W, m, sr):
//   irradiance at a surface point x from the illuminator at c_L:
//     E(x) = J0 * B(alpha) * cos(theta) / d^2  +  E_ambient * (1 + n_z) / 2
//   with d = |x - c_L|, theta between the surface normal and the direction to the light, alpha
//   the angle between the beam axis (the optical axis) and the direction from the light to x,
//   B(alpha) = cos(alpha)^m the beam pattern (B(0) = 1), J0 = efficiency * P * (m + 1) / (2 pi)
//   the axial radiant intensity of a beam that radiates efficiency * P watts, and the ambient
//   term a uniform sky hemisphere (a ground facing up gets all of it, a wall half).
//   Lambertian radiance L(x) = albedo(x) / pi * E(x). A glossy floor adds a mirror image with
//   Schlick-Fresnel weight (GlossyFloor). No shadows: the light sits a few centimetres from the
//   lens, so its shadows are slivers along depth edges.
//
// Anti-aliasing: ss x ss rays per pixel on a regular grid; subsamples that hit the same surface
// of the same primitive are shaded once at their mean hit point (as multisample anti-aliasing
// does on GPUs), with the texture band-limited to the pixel's footprint on the surface (see
// texture.hpp); pixels across geometric edges average the surfaces by coverage.
// Distance-independent texture (ShadingOptions::texture_footprint_m > 0): the texture is filtered
// to that fixed footprint in surface units instead of the pixel's, so a surface point has the same
// albedo from every distance and angle (the pixel-footprint filter makes it darker or lighter as
// fine detail fades with distance, which breaks the constant radiance that photometric
// calibration's ground truth assumes). Where a pixel's footprint is larger than that (far or
// grazing surfaces) the texture is then under-filtered: it aliases unless supersampling averages
// it. Lambertian-only shading drops the glossy floor's mirror term, whose radiance depends on the
// viewing direction.
// Motion blur: with one pose per subsample time slot, each subsample sees the scene at its own
// time within the exposure and is shaded on its own.

#include <memory>
#include <optional>
#include <span>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "nirslam/camera/camera_model.hpp"
#include "nirslam/geometry/se3.hpp"
#include "nirslam/sim/scene.hpp"

namespace nirslam::sim {

// The NIR illuminator: an 850 nm LED array beside the lens, its beam along the optical axis.
struct Illuminator {
  double power_w = 50.0;       // electrical power, as the paper's 0..150 W
  double efficiency = 0.35;    // radiated optical power / electrical power
  double half_angle_deg = 30.0;  // angle off the axis where the beam falls to half its intensity
  // Light position in the camera frame (x right, y down, z forward), metres.
  Eigen::Vector3d offset_cam = Eigen::Vector3d(0.0, 0.05, 0.0);

  // m in B(alpha) = cos(alpha)^m: ln(0.5) / ln(cos(half angle)).
  double beam_exponent() const;
  // B(alpha) in [0, 1]; 0 beyond 90 degrees.
  double beam(double alpha_rad) const;
  // J0, W/sr.
  double axial_intensity() const;
};

// How surfaces are shaded beyond the radiometry (see the header comment).
struct ShadingOptions {
  double texture_footprint_m = 0.0;  // 0: the texture follows the pixel footprint; > 0: this, fixed
  bool glossy_floor = true;                // false: Lambertian everywhere
};

struct Lighting {
  Illuminator illuminator;
  double ambient_irradiance = 0.0;  // W m^-2 from the sky hemisphere
  double sky_radiance = 0.0;        // W m^-2 sr^-1 of rays that leave the scene
};

class Renderer {
public:
  // supersampling: 1..4 rays per pixel side.
  Renderer(std::shared_ptr<const Scene> scene, std::shared_ptr<const CameraModel> camera, int supersampling = 2,
           ShadingOptions shading = {});

  const Scene& scene() const { return *scene_; }
  const CameraModel& camera() const { return *camera_; }
  int supersampling() const { return ss_; }
  const ShadingOptions& shading() const { return shading_; }
  // Subsample time slots for motion blur: one per subsample.
  int time_slots() const { return ss_ * ss_; }
  // The time slot of subsample (sx, sy), spread so time and position do not correlate.
  int slot_of(int sx, int sy) const;

  // Radiance per pixel (mean over its subsamples), CV_32FC1, into `radiance` (reallocated only
  // when its size or type differs). `poses` (T_world_cam) holds one pose, or one per time slot in
  // time order for motion blur. With `depth`, also writes the z (camera frame) of the surface hit
  // by each pixel's centre ray in the middle pose, 0 where the ray leaves the scene.
  void render(std::span<const SE3> poses, const Lighting& lighting, cv::Mat& radiance,
              cv::Mat* depth = nullptr) const;

  // Radiance and hit of one ray through `pixel` (for tests): the same shading as render() without
  // anti-aliasing, the texture filtered to the pixel footprint.
  struct PixelSample {
    double radiance = 0.0;
    double irradiance = 0.0;
    double albedo = 0.0;
    std::optional<SurfaceHit> hit;
  };
  PixelSample render_pixel(const SE3& pose, const Lighting& lighting, const Eigen::Vector2d& pixel) const;

private:
  struct Tile {
    int x0, y0, x1, y1;
    std::size_t offset;    // first pixel of the tile in the ray arrays
    Eigen::Vector3f axis;  // cone holding every ray of the tile, camera frame
    float cos_half, sin_half;
  };
  void build_rays();

  std::shared_ptr<const Scene> scene_;
  std::shared_ptr<const CameraModel> camera_;
  int ss_;
  ShadingOptions shading_;
  int width_, height_;
  // Per pixel, in tile order (see build_rays): ss*ss unit rays (zero when invalid), the centre
  // ray, the pixel's angular size (rad).
  std::vector<Eigen::Vector3f> sample_dirs_;
  std::vector<Eigen::Vector3f> centre_dirs_;
  std::vector<float> pixel_angle_;
  std::vector<Tile> tiles_;
};

}  // namespace nirslam::sim
