#include "rack/core/compute_worker.h"

namespace rack {

bool ComputeWorker::run(void (*fn)(void*), void* arg) noexcept {
  try {
    fn(arg);
    return true;
  } catch (...) {
    return false;  // said by wait()'s result: the poster decides what a failed job means
  }
}

void ComputeWorker::post_raw(void (*fn)(void*), void* arg) noexcept {
  rt::PiLock lock(mutex_);
  fn_ = fn;
  arg_ = arg;
  failed_ = false;
  if (serving_ && !stop_) {
    posted_ = true;
    cv_.notify_all();
  } else {
    inline_ = true;  // no thread will take it: wait() runs it
  }
}

bool ComputeWorker::wait() noexcept {
  void (*fn)(void*) = nullptr;
  void* arg = nullptr;
  {
    rt::PiLock lock(mutex_);
    if (!inline_) {
      // The serving thread runs a posted job before it looks at stop_ (serve()), so
      // this wait ends.
      while (posted_ || running_) (void)cv_.wait_until(mutex_, -1);
      const bool ok = !failed_;
      failed_ = false;  // said once
      return ok;
    }
    inline_ = false;
    fn = fn_;
    arg = arg_;
    ++inlined_;
  }
  return run(fn, arg);
}

bool ComputeWorker::serving() const noexcept {
  rt::PiLock lock(mutex_);
  return serving_;
}

void ComputeWorker::serve() noexcept {
  rt::PiLock lock(mutex_);
  serving_ = !stop_;
  for (;;) {
    if (posted_) {
      posted_ = false;
      running_ = true;
      void (*fn)(void*) = fn_;
      void* arg = arg_;
      mutex_.unlock();
      const bool ok = run(fn, arg);
      mutex_.lock();
      running_ = false;
      failed_ = !ok;
      ++served_;
      cv_.notify_all();
      continue;
    }
    if (stop_) break;
    (void)cv_.wait_until(mutex_, -1);
  }
  serving_ = false;
}

void ComputeWorker::stop() noexcept {
  rt::PiLock lock(mutex_);
  stop_ = true;
  cv_.notify_all();
}

uint64_t ComputeWorker::jobs_served() const noexcept {
  rt::PiLock lock(mutex_);
  return served_;
}

uint64_t ComputeWorker::jobs_inline() const noexcept {
  rt::PiLock lock(mutex_);
  return inlined_;
}

}  // namespace rack
