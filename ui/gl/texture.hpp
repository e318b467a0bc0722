#pragma once

#include <cstdint>

#include <imgui.h>
#include <opencv2/core/mat.hpp>

#include "ui/gl/gl.hpp"

namespace nirslam::ui::gl {

// A GL texture name as ImGui's renderer backend takes it.
inline ImTextureID texture_id(GLuint texture) {
  return reinterpret_cast<ImTextureID>(static_cast<std::uintptr_t>(texture));
}

// A single-channel texture holding a grey frame exactly: CV_8UC1 as GL_R8, CV_16UC1 as GL_R16
// (both normalised, so a shader reads code / 255 or code / 65535 and rescales by the frame's bit
// depth itself). Row 0 of the image is texture row t = 0. Move-only.
class GreyTexture {
public:
  GreyTexture() = default;
  ~GreyTexture();
  GreyTexture(GreyTexture&& other) noexcept;
  GreyTexture& operator=(GreyTexture&& other) noexcept;
  GreyTexture(const GreyTexture&) = delete;
  GreyTexture& operator=(const GreyTexture&) = delete;

  // Uploads the image, reusing the storage when size and depth are unchanged. Any row stride is
  // accepted (ROIs included). Throws std::invalid_argument for other types.
  void upload(const cv::Mat& image);

  GLuint id() const { return id_; }
  int width() const { return width_; }
  int height() const { return height_; }
  bool sixteen_bit() const { return sixteen_bit_; }
  bool empty() const { return id_ == 0 || width_ == 0 || height_ == 0; }
  // The largest code the container holds: 255 or 65535.
  float container_max() const { return sixteen_bit_ ? 65535.0f : 255.0f; }

private:
  GLuint id_ = 0;
  int width_ = 0;
  int height_ = 0;
  bool sixteen_bit_ = false;
};

}  // namespace nirslam::ui::gl
