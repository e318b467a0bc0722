#include "nirslam/image/frame.hpp"

#include <stdexcept>

namespace nirslam {

void validate_frame(const Frame& frame, const std::string& what) {
  if (frame.image.empty()) throw std::invalid_argument(what + ": empty image");
  const int type = frame.image.type();
  if (type == CV_8UC1) {
    if (frame.bit_depth != 8)
      throw std::invalid_argument(what + ": 8-bit image declares bit depth " +
                                  std::to_string(frame.bit_depth));
  } else if (type == CV_16UC1) {
    if (frame.bit_depth < 9 || frame.bit_depth > 16)
      throw std::invalid_argument(what + ": 16-bit image declares bit depth " +
                                  std::to_string(frame.bit_depth) + " (expected 9..16)");
  } else {
    throw std::invalid_argument(what + ": expected 8- or 16-bit single-channel grey image, got " +
                                std::to_string(frame.image.channels()) + " channel(s) of depth code " +
                                std::to_string(frame.image.depth()));
  }
}

}  // namespace nirslam
