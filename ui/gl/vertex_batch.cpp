#include "ui/gl/vertex_batch.hpp"

#include <algorithm>
#include <cstddef>
#include <utility>

namespace nirslam::ui::gl {

VertexBatch::~VertexBatch() { release(); }

VertexBatch::VertexBatch(VertexBatch&& other) noexcept
    : mode_(other.mode_),
      vertices_(std::move(other.vertices_)),
      vertex_array_(std::exchange(other.vertex_array_, 0)),
      buffer_(std::exchange(other.buffer_, 0)),
      capacity_(std::exchange(other.capacity_, 0)),
      uploaded_(std::exchange(other.uploaded_, 0)) {}

VertexBatch& VertexBatch::operator=(VertexBatch&& other) noexcept {
  if (this != &other) {
    release();
    mode_ = other.mode_;
    vertices_ = std::move(other.vertices_);
    vertex_array_ = std::exchange(other.vertex_array_, 0);
    buffer_ = std::exchange(other.buffer_, 0);
    capacity_ = std::exchange(other.capacity_, 0);
    uploaded_ = std::exchange(other.uploaded_, 0);
  }
  return *this;
}

void VertexBatch::release() {
  if (buffer_ != 0) glDeleteBuffers(1, &buffer_);
  if (vertex_array_ != 0) glDeleteVertexArrays(1, &vertex_array_);
  buffer_ = vertex_array_ = 0;
  capacity_ = uploaded_ = 0;
}

void VertexBatch::upload() {
  if (vertex_array_ == 0) {
    glGenVertexArrays(1, &vertex_array_);
    glGenBuffers(1, &buffer_);
    glBindVertexArray(vertex_array_);
    glBindBuffer(GL_ARRAY_BUFFER, buffer_);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, sizeof(ColouredVertex), nullptr);
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 4, GL_UNSIGNED_BYTE, GL_TRUE, sizeof(ColouredVertex),
                          reinterpret_cast<const void*>(offsetof(ColouredVertex, rgba)));
    glBindVertexArray(0);
  }
  glBindBuffer(GL_ARRAY_BUFFER, buffer_);
  const auto bytes = [](std::size_t n) { return static_cast<GLsizeiptr>(n * sizeof(ColouredVertex)); };
  if (vertices_.size() > capacity_) {
    capacity_ = std::max<std::size_t>(vertices_.size(), capacity_ + capacity_ / 2);
    glBufferData(GL_ARRAY_BUFFER, bytes(capacity_), nullptr, GL_DYNAMIC_DRAW);
  }
  if (!vertices_.empty()) glBufferSubData(GL_ARRAY_BUFFER, 0, bytes(vertices_.size()), vertices_.data());
  glBindBuffer(GL_ARRAY_BUFFER, 0);
  uploaded_ = vertices_.size();
}

void VertexBatch::draw() const {
  if (uploaded_ == 0 || vertex_array_ == 0) return;
  glBindVertexArray(vertex_array_);
  glDrawArrays(mode_, 0, static_cast<GLsizei>(uploaded_));
  glBindVertexArray(0);
}

}  // namespace nirslam::ui::gl
