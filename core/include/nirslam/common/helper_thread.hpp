#pragma once

// One persistent second thread for two-way splits (the machine this targets has two cores):
// run(on_caller, on_helper) runs on_helper on the helper thread and on_caller on the calling
// thread, and returns when both are done. The thread is started on the first run, not per call:
// the odometry's window splits its residual passes about ten times per keyframe, its epipolar
// searches and the photometric tracker's patches are split every frame, and starting a thread
// each time cost tens of microseconds plus a cold stack.

#include <condition_variable>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>

namespace nirslam {

class HelperThread {
public:
  HelperThread() = default;
  ~HelperThread();
  HelperThread(const HelperThread&) = delete;
  HelperThread& operator=(const HelperThread&) = delete;

  // Runs both and waits for both; an exception of either is rethrown (the caller's first).
  // Calls from several threads are served one at a time.
  void run(const std::function<void()>& on_caller, const std::function<void()>& on_helper);

private:
  void loop();

  std::mutex run_mutex_;  // one run() at a time
  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable finished_;
  const std::function<void()>* job_ = nullptr;
  bool job_done_ = false;
  bool stop_ = false;
  std::exception_ptr job_error_;
  std::thread thread_;
};

// Runs body(begin, end, part) over [0, count) split in two at `split` (part 0 on the caller,
// part 1 on the helper); counts below `min_count` stay on the caller as one part.
template <typename Body>
void split_in_two(HelperThread& helper, std::size_t count, std::size_t split, std::size_t min_count, Body&& body) {
  if (count < min_count) {
    body(std::size_t{0}, count, 0);
    return;
  }
  helper.run([&] { body(std::size_t{0}, split, 0); }, [&] { body(split, count, 1); });
}

}  // namespace nirslam
