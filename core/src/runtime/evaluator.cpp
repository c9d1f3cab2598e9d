#include "runtime/evaluator.hpp"

#include <qd/errors.hpp>

#include <algorithm>

namespace qd::runtime {

int hardware_workers() {
  const unsigned n = std::thread::hardware_concurrency();
  return n == 0 ? 1 : static_cast<int>(n);
}

WorkerPool::WorkerPool(int threads) {
  for (int i = 1; i < threads; ++i) threads_.emplace_back([this] { work(); });
}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  for (auto& t : threads_) t.join();
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
  ++generation_;
  wake_.notify_all();
  // The caller works too.
  while (next_ < n_) {
    const std::size_t i = next_++;
    lock.unlock();
    fn(i);
    lock.lock();
    ++finished_;
  }
  done_.wait(lock, [&] { return finished_ == n_ && busy_ == 0; });
  job_ = nullptr;
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
      const auto* fn = job_;
      lock.unlock();
      (*fn)(i);
      lock.lock();
      ++finished_;
    }
    --busy_;
    if (finished_ == n_ && busy_ == 0) done_.notify_all();
  }
}

Evaluator::Evaluator(const Environment& env, const Descriptor& desc, const PolicyShape& shape, int workers)
    : env_(env), desc_(desc), shape_(shape), dims_(desc.grid().shape.size()), pool_(workers) {}

void Evaluator::evaluate(const Matrix& params, const std::vector<std::uint64_t>& seeds, Evaluations& out) {
  const auto n = static_cast<std::size_t>(params.rows());
  QD_CHECK(seeds.size() == n, "one episode seed per row");
  out.traces.resize(n);
  out.cells.assign(n, -1);
  out.descriptors.setZero(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(dims_));
  // Chunks keep dispatch at one virtual call per chunk while leaving enough chunks for dynamic
  // load balancing; with one worker the whole batch is one call.
  const std::size_t workers = static_cast<std::size_t>(pool_.size());
  const std::size_t chunk = workers == 1 ? std::max<std::size_t>(n, 1) : std::max<std::size_t>(1, n / (workers * 8));
  const std::size_t chunks = (n + chunk - 1) / chunk;
  pool_.run(chunks, [&](std::size_t c) {
    RolloutBatch b;
    b.shape = &shape_;
    b.params = &params;
    b.episode_seeds = seeds.data();
    b.begin = c * chunk;
    b.end = std::min(n, b.begin + chunk);
    for (std::size_t i = b.begin; i < b.end; ++i) out.traces[i].clear();
    env_.rollout(b, out.traces.data());
    for (std::size_t i = b.begin; i < b.end; ++i)
      if (out.traces[i].status == EvalStatus::kOk)
        desc_.describe(&out.traces[i], 1, &out.cells[i], out.descriptors.row(static_cast<Eigen::Index>(i)).data());
  });
}

}  // namespace qd::runtime
