#include "runtime/row_copier.hpp"

#include <pthread.h>
#include <utility>

namespace qd::runtime {

RowCopier::RowCopier(Archive& archive) : archive_(archive), thread_([this] { work(); }) {}

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
  {
    std::lock_guard<std::mutex> lock(mutex_);
    queue_.push_back(std::move(copies));
    ++submitted_;
    copies.clear();
    if (!spare_.empty()) {
      copies.swap(spare_.back());
      spare_.pop_back();
    }
  }
  wake_.notify_one();
}

void RowCopier::wait(std::uint64_t in_flight) {
  std::vector<std::vector<Archive::DeferredCopy>> done;
  {
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [&] { return submitted_ - completed_ <= in_flight; });
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
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    wake_.wait(lock, [&] { return stop_ || !queue_.empty(); });
    if (queue_.empty()) return;
    std::vector<Archive::DeferredCopy> batch = std::move(queue_.front());
    queue_.pop_front();
    lock.unlock();
    archive_.complete_copies(batch);
    lock.lock();
    completed_batches_.push_back(std::move(batch));
    ++completed_;
    done_.notify_all();
  }
}

}  // namespace qd::runtime
