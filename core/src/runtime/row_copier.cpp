#include "runtime/row_copier.hpp"

#include <pthread.h>
#include <algorithm>
#include <utility>

#if defined(__SSE2__)
#include <immintrin.h>
#endif

namespace qd::runtime {

RowCopier::RowCopier(Archive& archive, bool poll) : archive_(archive), poll_(poll), thread_([this] { work(); }) {}

RowCopier::~RowCopier() {
  wait();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void RowCopier::submit(std::vector<Archive::DeferredCopy>& copies) {
  bool wake = false;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    queue_.push_back(std::move(copies));
    ++submitted_;
    copies.clear();
    if (!spare_.empty()) {
      copies.swap(spare_.back());
      spare_.pop_back();
    }
    wake = blocked_;
  }
  if (wake) wake_.notify_one();
}

bool RowCopier::copy_next(std::unique_lock<std::mutex>& lock) {
  if (queue_.empty() || copying_) return false;
  std::vector<Archive::DeferredCopy> batch = std::move(queue_.front());
  queue_.pop_front();
  copying_ = true;
  lock.unlock();
  archive_.complete_copies(batch);
  lock.lock();
  copying_ = false;
  completed_batches_.push_back(std::move(batch));
  ++completed_;
  return true;
}

void RowCopier::wait(std::uint64_t in_flight) {
  std::vector<std::vector<Archive::DeferredCopy>> done;
  const auto now = std::chrono::steady_clock::now();
  {
    std::unique_lock<std::mutex> lock(mutex_);
    if (last_wait_ != std::chrono::steady_clock::time_point{})
      poll_interval_ =
          std::clamp<std::chrono::steady_clock::duration>((now - last_wait_) / kPollsPerBatch, kMinPoll, kMaxPoll);
    last_wait_ = now;
    while (submitted_ - completed_ > in_flight) {
      if (copy_next(lock)) continue;
      // The copier is copying a batch (at most one batch's rows): spin rather than block, which
      // would need a wake-up in return.
      lock.unlock();
#if defined(__SSE2__)
      _mm_pause();
#endif
      std::this_thread::yield();
      lock.lock();
    }
    done.swap(completed_batches_);
  }
  for (auto& batch : done) {
    archive_.release_copies(batch);
    batch.clear();
  }
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto& batch : done) spare_.push_back(std::move(batch));
}

void RowCopier::work() {
  ::pthread_setname_np(::pthread_self(), "qd-row-copier");  // named for top -H and the benchmark
  using Clock = std::chrono::steady_clock;
  std::unique_lock<std::mutex> lock(mutex_);
  Clock::time_point last_work = Clock::now();
  for (;;) {
    if (copy_next(lock)) {
      if (poll_) last_work = Clock::now();
      continue;
    }
    if (stop_ && queue_.empty() && !copying_) return;
    if (!poll_ || Clock::now() - last_work > kIdleTimeout) {
      blocked_ = true;
      wake_.wait(lock, [&] { return stop_ || (!queue_.empty() && !copying_); });
      blocked_ = false;
      last_work = Clock::now();
      continue;
    }
    const auto interval = poll_interval_;
    lock.unlock();
    std::this_thread::sleep_for(interval);
    lock.lock();
  }
}

}  // namespace qd::runtime
