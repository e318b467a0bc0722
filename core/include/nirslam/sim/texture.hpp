#pragma once

// Procedural NIR albedo patterns, evaluated from surface coordinates of the 3-D hit point, so
// there is no texture map to alias. Every pattern is band-limited to the footprint of a pixel on
// the surface: noise octaves finer than the footprint fade to their mean, and edges (grout,
// joints, book spines, window frames, markings) are box-filtered steps of the footprint's width.
// With that, one albedo evaluation per pixel and surface is already anti-aliased; supersampling
// then only has to resolve geometric edges.

#include <cstdint>

#include "nirslam/sim/scene.hpp"

namespace nirslam::sim {

// Albedo in [0, 1] of `material` at surface coordinates (u, v) in metres (v is height on
// vertical faces; horizontal faces use world x, y; tubes use arc length and the axis).
// `footprint` is the pixel's size on the surface in metres (0: no filtering); `seed` varies the
// pattern between objects.
float material_albedo(Material material, float u, float v, float footprint, std::uint32_t seed);

// Smooth value noise in [0, 1] at (x, y) (lattice period 1, tiles every 256), for tests.
float value_noise(float x, float y);

}  // namespace nirslam::sim
