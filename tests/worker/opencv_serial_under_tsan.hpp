#pragma once

// Under ThreadSanitizer, OpenCV's loops run serially for every worker test that includes this.

#include <opencv2/core/utility.hpp>

#if defined(__SANITIZE_THREAD__)  // GCC
#define NIRSLAM_UNDER_TSAN 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)  // Clang
#define NIRSLAM_UNDER_TSAN 1
#endif
#endif

namespace nirslam {

#if defined(NIRSLAM_UNDER_TSAN)
// OpenCV's parallel_for_ runs on TBB, which is not instrumented: ThreadSanitizer cannot see its
// synchronisation and reports races inside it. The worker's own threads are what these tests
// check, so OpenCV runs its loops serially on the calling thread here (set once, before main).
inline const bool opencv_loops_serial = [] {
  cv::setNumThreads(0);
  return true;
}();
#endif

}  // namespace nirslam
