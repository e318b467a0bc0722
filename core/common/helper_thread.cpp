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

void HelperThread::loop() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    wake_.wait(lock, [this] { return stop_ || job_ != nullptr; });
    if (stop_) return;
    const std::function<void()>* job = job_;
    lock.unlock();
    std::exception_ptr error;
    try {
      (*job)();
    } catch (...) {
      error = std::current_exception();
    }
    lock.lock();
    job_ = nullptr;
    job_error_ = error;
    job_done_ = true;
    finished_.notify_one();
  }
}

void HelperThread::run(const std::function<void()>& on_caller, const std::function<void()>& on_helper) {
  std::lock_guard<std::mutex> serial(run_mutex_);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!thread_.joinable()) thread_ = std::thread([this] { loop(); });
    job_ = &on_helper;
    job_done_ = false;
    job_error_ = nullptr;
  }
  wake_.notify_one();
  std::exception_ptr caller_error;
  try {
    on_caller();
  } catch (...) {
    caller_error = std::current_exception();
  }
  std::exception_ptr helper_error;
  {
    std::unique_lock<std::mutex> lock(mutex_);
    finished_.wait(lock, [this] { return job_done_; });
    helper_error = job_error_;
  }
  if (caller_error) std::rethrow_exception(caller_error);
  if (helper_error) std::rethrow_exception(helper_error);
}

}  // namespace nirslam
