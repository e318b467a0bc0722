#pragma once

#include <cstddef>
#include <memory>

#include "nirslam/sources/source.hpp"

namespace nirslam {

// Reads up to `depth` frames ahead of the consumer on a thread of its own, so decoding (2-3 ms a
// 640x480 PNG) overlaps the pipeline instead of preceding it. The frames, their order and the
// errors are those of `source`: a frame that fails to read throws from next() at its place in
// the stream, after every frame read before it.
//
// Only for recorded sequences: a live source (which paces and drops frames itself) and one that
// drives its own illuminator (frames read ahead would miss a power change) are returned as they
// are, and so is everything when `depth` is 0.
std::unique_ptr<Source> read_ahead(std::unique_ptr<Source> source, std::size_t depth = 4);

}  // namespace nirslam
