#include "ui/gl/texture.hpp"

#include <stdexcept>
#include <string>
#include <utility>

namespace nirslam::ui::gl {

GreyTexture::~GreyTexture() {
  if (id_ != 0) glDeleteTextures(1, &id_);
}

GreyTexture::GreyTexture(GreyTexture&& other) noexcept
    : id_(std::exchange(other.id_, 0)),
      width_(std::exchange(other.width_, 0)),
      height_(std::exchange(other.height_, 0)),
      sixteen_bit_(std::exchange(other.sixteen_bit_, false)) {}

GreyTexture& GreyTexture::operator=(GreyTexture&& other) noexcept {
  if (this != &other) {
    if (id_ != 0) glDeleteTextures(1, &id_);
    id_ = std::exchange(other.id_, 0);
    width_ = std::exchange(other.width_, 0);
    height_ = std::exchange(other.height_, 0);
    sixteen_bit_ = std::exchange(other.sixteen_bit_, false);
  }
  return *this;
}

void GreyTexture::upload(const cv::Mat& image) {
  if (image.type() != CV_8UC1 && image.type() != CV_16UC1)
    throw std::invalid_argument("GreyTexture: expected a CV_8UC1 or CV_16UC1 image, got type " +
                                std::to_string(image.type()));
  if (image.empty()) throw std::invalid_argument("GreyTexture: empty image");
  const bool sixteen = image.type() == CV_16UC1;
  const GLenum type = sixteen ? GL_UNSIGNED_SHORT : GL_UNSIGNED_BYTE;

  GLint previous_texture = 0;
  glGetIntegerv(GL_TEXTURE_BINDING_2D, &previous_texture);
  if (id_ == 0) {
    glGenTextures(1, &id_);
    glBindTexture(GL_TEXTURE_2D, id_);
    // Magnified pixels stay crisp squares (the operator zooms in to inspect them); minified ones
    // are averaged so a large frame in a small panel does not alias.
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  } else {
    glBindTexture(GL_TEXTURE_2D, id_);
  }

  GLint previous_alignment = 4;
  GLint previous_row_length = 0;
  glGetIntegerv(GL_UNPACK_ALIGNMENT, &previous_alignment);
  glGetIntegerv(GL_UNPACK_ROW_LENGTH, &previous_row_length);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glPixelStorei(GL_UNPACK_ROW_LENGTH, static_cast<GLint>(image.step1()));

  if (width_ != image.cols || height_ != image.rows || sixteen_bit_ != sixteen) {
    glTexImage2D(GL_TEXTURE_2D, 0, sixteen ? GL_R16 : GL_R8, image.cols, image.rows, 0, GL_RED, type,
                 image.data);
    width_ = image.cols;
    height_ = image.rows;
    sixteen_bit_ = sixteen;
  } else {
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, image.cols, image.rows, GL_RED, type, image.data);
  }

  glPixelStorei(GL_UNPACK_ALIGNMENT, previous_alignment);
  glPixelStorei(GL_UNPACK_ROW_LENGTH, previous_row_length);
  glBindTexture(GL_TEXTURE_2D, static_cast<GLuint>(previous_texture));
}

}  // namespace nirslam::ui::gl
