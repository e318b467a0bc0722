#pragma once

// One persistent second thread for two-way splits (the machine this targets has two cores):
// run(part_0, part_1) runs both parts, each exactly once, on the calling thread and the helper,
// and returns when both are done. Which thread runs a part is decided at run time: the caller
// takes a part as soon as it is free, so when the helper is not scheduled (a loaded machine) the
// caller runs both parts itself instead of waiting for it; a part's result must therefore not
// depend on the thread that runs it (every user keeps its sums per part, not per thread). The
// thread is started on the first run, not per call: the odometry's window splits its residual
// passes about ten times per keyframe, its searches and the photometric tracker's patches are
// split every frame, and starting a thread each time cost tens of microseconds plus a cold stack.

#include <condition_variable>
#include <cstddef>
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

  // Runs both parts and waits for both; an exception of either is rethrown (part 0's first).
  // Calls from several threads are served one at a time.
  void run(const std::function<void()>& part_0, const std::function<void()>& part_1);

private:
  void loop();
  // Claims the next part of the current job, or -1 when none is left (or the job is withdrawn).
  int claim(std::unique_lock<std::mutex>& lock);
  void run_part(int part, std::unique_lock<std::mutex>& lock);

  std::mutex run_mutex_;  // one run() at a time
  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable finished_;
  const std::function<void()>* parts_[2] = {nullptr, nullptr};
  bool job_open_ = false;  // parts may still be claimed
  int next_part_ = 2;      // next unclaimed part
  int running_ = 0;        // parts claimed and not finished
  std::exception_ptr errors_[2];
  std::size_t generation_ = 0;  // jobs posted so far
  bool stop_ = false;
  std::thread thread_;
};

// Runs body(begin, end, part) over [0, count) split in two at `split` (parts 0 and 1, on
// whichever thread is free); counts below `min_count` run on the caller as one part 0.
template <typename Body>
void split_in_two(HelperThread& helper, std::size_t count, std::size_t split, std::size_t min_count, Body&& body) {
  if (count < min_count) {
    body(std::size_t{0}, count, 0);
    return;
  }
  helper.run([&] { body(std::size_t{0}, split, 0); }, [&] { body(split, count, 1); });
}

}  // namespace nirslam
