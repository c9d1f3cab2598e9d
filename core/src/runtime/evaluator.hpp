// Runs rollouts and descriptors for a batch, serially or on local threads.
//
// Determinism: every result is written into its own slot (indexed by offspring), and nothing in a
// rollout depends on which thread runs it, so 1 and N workers give identical results.
#pragma once

#include <qd/descriptor.hpp>
#include <qd/environment.hpp>
#include <qd/policy.hpp>
#include <qd/types.hpp>

#include <condition_variable>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace qd::runtime {

struct Evaluations {
  std::vector<Trace> traces;
  std::vector<std::int64_t> cells;  // -1 = not insertable (failed or undescribable)
  Matrix descriptors;               // n × dims
};

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
  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  const std::function<void(std::size_t)>* job_ = nullptr;
  std::size_t n_ = 0, next_ = 0, finished_ = 0;
  std::uint64_t generation_ = 0;
  int busy_ = 0;
  bool stop_ = false;
};

class Evaluator {
 public:
  Evaluator(const Environment& env, const Descriptor& desc, const PolicyShape& shape, int workers);

  int workers() const noexcept { return pool_.size(); }
  void evaluate(const Matrix& params, const std::vector<std::uint64_t>& episode_seeds, Evaluations& out);

 private:
  const Environment& env_;
  const Descriptor& desc_;
  PolicyShape shape_;
  std::size_t dims_;
  WorkerPool pool_;
};

// Number of hardware threads (at least 1).
int hardware_workers();

}  // namespace qd::runtime
