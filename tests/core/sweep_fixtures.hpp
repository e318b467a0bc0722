#pragma once

// A power sweep folder made at test time: a textured wall lit by a lamp of power P, seen by an
// 8-bit camera with a gamma response, dark noise and clipping at full scale; sweep.csv names each
// image's power. Brighter with power, so entropy rises, saturates, and falls once the wall clips.
// With `highlights`, 2 % of the wall are reflectors four times brighter than its brightest paint:
// they clip at a quarter of the power the wall needs.

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "nirslam/image/image_codec.hpp"

namespace nirslam::testing {

inline cv::Mat sweep_wall(int width, int height, unsigned seed, bool highlights = false) {
  cv::RNG rng(seed);
  cv::Mat albedo(height, width, CV_32FC1, cv::Scalar(0.35f));
  for (int i = 0; i < 160; ++i) {
    const cv::Point a(rng.uniform(0, width), rng.uniform(0, height));
    const cv::Size s(rng.uniform(6, 80), rng.uniform(6, 80));
    cv::rectangle(albedo, cv::Rect(a, s), cv::Scalar(rng.uniform(0.05f, 0.95f)), cv::FILLED);
  }
  cv::GaussianBlur(albedo, albedo, cv::Size(3, 3), 0.8);
  if (highlights)
    for (int i = 0; i < 24; ++i)
      albedo(cv::Rect(12 + (i % 6) * 50, 20 + (i / 6) * 55, 8, 8)).setTo(4.0f);
  return albedo;
}

// The image of `albedo` at `power_w`: irradiance power / full_power at the brightest albedo.
inline cv::Mat sweep_image(const cv::Mat& albedo, double power_w, double full_power_w, unsigned noise_seed) {
  cv::Mat signal = albedo * (power_w / full_power_w);
  cv::Mat noise(albedo.size(), CV_32FC1);
  cv::RNG(noise_seed).fill(noise, cv::RNG::NORMAL, 0.0, 0.004);
  signal += noise;
  cv::max(signal, 0.0, signal);
  cv::pow(signal, 1.0 / 2.2, signal);
  cv::Mat image;
  signal.convertTo(image, CV_8UC1, 255.0);  // saturates at 255
  return image;
}

// Writes `frames_per_power` images per power and sweep.csv ("file,power_w" plus an extra column the
// reader must ignore) into `folder`.
inline void write_sweep_folder(const std::filesystem::path& folder, const std::vector<double>& powers_w,
                               double full_power_w, int frames_per_power = 2, const std::string& scene = {},
                               bool highlights = false) {
  std::filesystem::create_directories(folder / "images");
  const cv::Mat albedo = sweep_wall(320, 240, 11, highlights);
  std::ofstream csv(folder / "sweep.csv");
  csv << "file,exposure_ms,power_w" << (scene.empty() ? "" : ",scene") << "\n";
  int index = 0;
  for (const double power : powers_w) {
    for (int k = 0; k < frames_per_power; ++k, ++index) {
      const std::string name = "images/" + std::to_string(index) + ".png";
      nirslam::write_image(folder / name, sweep_image(albedo, power, full_power_w, 100u + static_cast<unsigned>(index)));
      csv << name << ",10.0," << power << (scene.empty() ? "" : "," + scene) << "\n";
    }
  }
}

}  // namespace nirslam::testing
