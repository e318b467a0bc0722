#include "nirslam/common/helper_thread.hpp"

namespace nirslam {

HelperThread::~HelperThread() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_one();
  if (thread_.joinable()) thread_.join();
}

int HelperThread::claim(std::unique_lock<std::mutex>&) {
  if (!job_open_ || next_part_ >= 2) return -1;
  ++running_;
  return next_part_++;
}

void HelperThread::run_part(int part, std::unique_lock<std::mutex>& lock) {
  const std::function<void()>* job = parts_[part];
  lock.unlock();
  std::exception_ptr error;
  try {
    (*job)();
  } catch (...) {
    error = std::current_exception();
  }
  lock.lock();
  errors_[part] = error;
  --running_;
  if (running_ == 0) finished_.notify_all();
}

void HelperThread::loop() {
  std::unique_lock<std::mutex> lock(mutex_);
  std::size_t seen = 0;
  for (;;) {
    wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
    if (stop_) return;
    seen = generation_;
    // The caller may have taken both parts already; then there is nothing to do.
    for (int part = claim(lock); part >= 0; part = claim(lock)) run_part(part, lock);
  }
}

void HelperThread::run(const std::function<void()>& part_0, const std::function<void()>& part_1) {
  std::lock_guard<std::mutex> serial(run_mutex_);
  std::unique_lock<std::mutex> lock(mutex_);
  if (!thread_.joinable()) thread_ = std::thread([this] { loop(); });
  parts_[0] = &part_0;
  parts_[1] = &part_1;
  errors_[0] = errors_[1] = nullptr;
  next_part_ = 0;
  running_ = 0;
  job_open_ = true;
  ++generation_;
  wake_.notify_one();
  for (int part = claim(lock); part >= 0; part = claim(lock)) run_part(part, lock);
  // Nothing left to claim: wait only for a part the helper is running, then withdraw the job so
  // a helper that wakes late finds nothing (the parts live on the caller's stack).
  finished_.wait(lock, [this] { return running_ == 0; });
  job_open_ = false;
  parts_[0] = parts_[1] = nullptr;
  if (errors_[0]) std::rethrow_exception(errors_[0]);
  if (errors_[1]) std::rethrow_exception(errors_[1]);
}

}  // namespace nirslam
