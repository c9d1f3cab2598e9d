// The threads of the "threads" backend (and of replay): a fixed pool in which the calling thread
// works too.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace qd::runtime {

// A tiny fixed pool: the calling thread works too, workers pull indices from a shared counter
// (dynamic load balancing: episodes differ in length).
class WorkerPool {
 public:
  explicit WorkerPool(int threads);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  int size() const noexcept { return static_cast<int>(threads_.size()) + 1; }
  // Calls fn(i) for every i in [0, n), possibly concurrently; returns when all are done.
  void run(std::size_t n, const std::function<void(std::size_t)>& fn);

 private:
  void work();
  void stop();  // ends and joins the threads
  // fn(i) with the lock released. The first exception ends the job: no further index is handed
  // out, and run() rethrows it once every call in progress has returned (the job and everything
  // it refers to live in run()'s caller, so no thread may still use them after run() returns).
  void call(std::size_t i, const std::function<void(std::size_t)>& fn, std::unique_lock<std::mutex>& lock);
  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  const std::function<void(std::size_t)>* job_ = nullptr;
  std::size_t n_ = 0, next_ = 0, finished_ = 0;
  std::uint64_t generation_ = 0;
  std::exception_ptr error_;
  int busy_ = 0;
  bool stop_ = false;
};

}  // namespace qd::runtime
