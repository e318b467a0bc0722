#include "ui/colour_maps.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "ui/theme.hpp"

namespace nirslam::ui {
namespace {

struct Stop {
  float r, g, b;
};

template <std::size_t N>
ImU32 ramp(const std::array<Stop, N>& stops, float t) {
  t = std::clamp(std::isfinite(t) ? t : 0.0f, 0.0f, 1.0f);
  const float position = t * static_cast<float>(N - 1);
  const std::size_t i = std::min(static_cast<std::size_t>(position), N - 2);
  const float f = position - static_cast<float>(i);
  const auto mix = [f](float a, float b) { return static_cast<unsigned>(std::lround(255.0f * (a + f * (b - a)))); };
  return rgba(mix(stops[i].r, stops[i + 1].r), mix(stops[i].g, stops[i + 1].g), mix(stops[i].b, stops[i + 1].b));
}

// Sampled from the turbo colour map (Mikhailov 2019) at 0, 1/6, ..., 1.
constexpr std::array<Stop, 7> kTurbo{{{0.19f, 0.07f, 0.23f},
                                      {0.27f, 0.51f, 0.99f},
                                      {0.10f, 0.90f, 0.71f},
                                      {0.64f, 0.99f, 0.24f},
                                      {0.98f, 0.73f, 0.22f},
                                      {0.89f, 0.27f, 0.04f},
                                      {0.48f, 0.02f, 0.01f}}};
constexpr std::array<Stop, 3> kError{{{0.20f, 0.80f, 0.35f}, {0.97f, 0.85f, 0.20f}, {0.92f, 0.20f, 0.16f}}};
constexpr std::array<Stop, 5> kHeat{{{0.0f, 0.0f, 0.02f},
                                     {0.32f, 0.07f, 0.50f},
                                     {0.72f, 0.21f, 0.47f},
                                     {0.98f, 0.55f, 0.24f},
                                     {0.99f, 0.99f, 0.75f}}};

}  // namespace

ImU32 time_colour(float t) { return ramp(kTurbo, 0.08f + 0.84f * t); }  // the darkest ends vanish on the dark theme
ImU32 error_colour(float t) { return ramp(kError, t); }
ImU32 heat_colour(float t) { return ramp(kHeat, t); }

}  // namespace nirslam::ui
