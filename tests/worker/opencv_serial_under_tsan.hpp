#pragma once

// Under ThreadSanitizer, OpenCV's loops run serially for every worker test that includes this.

#include <opencv2/core/utility.hpp>

namespace nirslam {

#if defined(__SANITIZE_THREAD__)
// OpenCV's parallel_for_ runs on TBB, which is not instrumented: ThreadSanitizer cannot see its
// synchronisation and reports races inside it. The worker's own threads are what these tests
// check, so OpenCV runs its loops serially on the calling thread here (set once, before main).
inline const bool opencv_loops_serial = [] {
  cv::setNumThreads(0);
  return true;
}();
#endif

}  // namespace nirslam
