#include "runtime/worker_pool.hpp"

#include <qd/errors.hpp>

#include <string>
#include <system_error>

namespace qd::runtime {

WorkerPool::WorkerPool(int threads) {
  try {
    for (int i = 1; i < threads; ++i) threads_.emplace_back([this] { work(); });
  } catch (const std::system_error& e) {
    // The threads made so far wait on this object's condition variable: stop and join them before
    // the members they use are destroyed (a container's thread limit, ulimit -u).
    stop();
    throw SystemError("cannot create evaluation thread " + std::to_string(threads_.size() + 1) + " of " +
                      std::to_string(threads - 1) + ": " + e.what() + "; use fewer --workers");
  }
}

WorkerPool::~WorkerPool() {
  stop();
}

void WorkerPool::stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  for (auto& t : threads_) t.join();
  threads_.clear();
}

void WorkerPool::run(std::size_t n, const std::function<void(std::size_t)>& fn) {
  if (threads_.empty() || n <= 1) {
    for (std::size_t i = 0; i < n; ++i) fn(i);
    return;
  }
  std::unique_lock<std::mutex> lock(mutex_);
  job_ = &fn;
  n_ = n;
  next_ = 0;
  finished_ = 0;
  error_ = nullptr;
  ++generation_;
  wake_.notify_all();
  // The caller works too.
  while (next_ < n_) {
    const std::size_t i = next_++;
    call(i, fn, lock);
  }
  done_.wait(lock, [&] { return finished_ == n_ && busy_ == 0; });
  job_ = nullptr;
  if (error_) {
    std::exception_ptr error = std::move(error_);
    error_ = nullptr;
    lock.unlock();
    std::rethrow_exception(error);
  }
}

void WorkerPool::call(std::size_t i, const std::function<void(std::size_t)>& fn, std::unique_lock<std::mutex>& lock) {
  lock.unlock();
  std::exception_ptr error;
  try {
    fn(i);
  } catch (...) {
    error = std::current_exception();
  }
  lock.lock();
  ++finished_;
  if (error) {
    if (!error_) error_ = std::move(error);
    finished_ += n_ - next_;  // the indices never handed out count as done
    next_ = n_;
  }
}

void WorkerPool::work() {
  std::uint64_t seen = 0;
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    wake_.wait(lock, [&] { return stop_ || (generation_ != seen && job_ && next_ < n_); });
    if (stop_) return;
    seen = generation_;
    ++busy_;
    while (job_ && next_ < n_) {
      const std::size_t i = next_++;
      call(i, *job_, lock);
    }
    --busy_;
    if (finished_ == n_ && busy_ == 0) done_.notify_all();
  }
}

}  // namespace qd::runtime
