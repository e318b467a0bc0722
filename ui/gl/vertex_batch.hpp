#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "ui/gl/gl.hpp"

namespace nirslam::ui::gl {

// A vertex of the 3-D view: position and RGBA8 colour (as ImU32: R in the low byte), 16 bytes.
struct ColouredVertex {
  float x = 0.0f;
  float y = 0.0f;
  float z = 0.0f;
  std::uint32_t rgba = 0;
};

// Vertices drawn as points, lines or a line strip with shaders/scene.{vert,frag}. Filled on the
// CPU, uploaded once per change (the buffer grows, never shrinks, so steady updates do not
// reallocate). Move-only; needs the GL context that created it.
class VertexBatch {
public:
  explicit VertexBatch(GLenum mode = GL_LINES) : mode_(mode) {}
  ~VertexBatch();
  VertexBatch(VertexBatch&& other) noexcept;
  VertexBatch& operator=(VertexBatch&& other) noexcept;
  VertexBatch(const VertexBatch&) = delete;
  VertexBatch& operator=(const VertexBatch&) = delete;

  void clear() { vertices_.clear(); }
  void add(const Eigen::Vector3f& p, std::uint32_t rgba) { vertices_.push_back({p.x(), p.y(), p.z(), rgba}); }
  void add_line(const Eigen::Vector3f& a, const Eigen::Vector3f& b, std::uint32_t rgba) {
    add(a, rgba);
    add(b, rgba);
  }
  std::size_t size() const { return vertices_.size(); }
  std::vector<ColouredVertex>& vertices() { return vertices_; }

  void upload();
  void draw() const;  // with the scene program in use

private:
  void release();
  GLenum mode_;
  std::vector<ColouredVertex> vertices_;
  GLuint vertex_array_ = 0;
  GLuint buffer_ = 0;
  std::size_t capacity_ = 0;  // vertices the GL buffer holds
  std::size_t uploaded_ = 0;  // vertices drawn
};

}  // namespace nirslam::ui::gl
