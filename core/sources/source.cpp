#include "nirslam/sources/source.hpp"

#include <stdexcept>

#include <fmt/format.h>

namespace nirslam {

void Source::seek(std::size_t /*position*/) {
  throw std::logic_error(fmt::format("{}: this source cannot jump to a frame ({} frames come as they are delivered)",
                                     info().description, info().live ? "live" : "generated"));
}

void Source::require_frame_position(std::size_t position, std::size_t frame_count) const {
  if (position >= frame_count)
    throw std::out_of_range(fmt::format("{}: cannot seek to frame {}, the sequence has {} frames", info().description,
                                        position, frame_count));
}

}  // namespace nirslam
