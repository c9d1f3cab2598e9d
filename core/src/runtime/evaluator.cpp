#include "runtime/evaluator.hpp"

#include "runtime/plugin_call.hpp"
#include "runtime/process_evaluator.hpp"

#include <qd/errors.hpp>

#include <unistd.h>
#include <algorithm>
#include <cstdlib>
#include <string>
#include <system_error>

namespace qd::runtime {

int hardware_workers() {
  const unsigned n = std::thread::hardware_concurrency();
  return n == 0 ? 1 : static_cast<int>(n);
}

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

void Evaluations::reset(std::size_t n, std::size_t dims) {
  status.assign(n, EvalStatus::kOk);
  steps.assign(n, 0);
  fitness.assign(n, 0.0);
  cells.assign(n, -1);
  descriptors.setZero(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(dims));
}

void unpack_records(const double* records, std::size_t begin, std::size_t end, std::size_t dims, Evaluations& out) {
  const std::size_t w = record_width(dims);
  for (std::size_t i = begin; i < end; ++i) {
    const double* r = records + (i - begin) * w;
    out.status[i] = static_cast<EvalStatus>(static_cast<int>(r[0]));
    out.steps[i] = static_cast<std::int32_t>(r[1]);
    out.fitness[i] = r[2];
    out.cells[i] = static_cast<std::int64_t>(r[3]);
    for (std::size_t d = 0; d < dims; ++d)
      out.descriptors(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(d)) = r[kRecordHead + d];
  }
}

namespace {
std::string what_of(const std::exception_ptr& e) {
  try {
    std::rethrow_exception(e);
  } catch (const std::exception& x) {
    return x.what();
  } catch (...) {
    return "an exception that is not a std::exception";
  }
}
}  // namespace

void guarded_rollout(const Environment& env, const std::string& label, const RolloutBatch& b, Trace* traces,
                     std::size_t offset) {
  const PluginCallScope scope(label, "rollout()");
  std::exception_ptr error;
  try {
    env.rollout(b, traces);
    return;
  } catch (...) {
    error = std::current_exception();
  }
  if (b.end - b.begin > 1) {
    for (std::size_t i = b.begin; i < b.end; ++i) {
      RolloutBatch one = b;
      one.begin = i;
      one.end = i + 1;
      traces[i].clear();
      try {
        env.rollout(one, traces);
      } catch (...) {
        throw EvaluationFault(label + " threw from rollout(): " + what_of(std::current_exception()), offset + i,
                              offset + i);
      }
    }
  }
  throw EvaluationFault(label + " threw from rollout(): " + what_of(error), offset + b.begin, offset + b.end - 1);
}

void guarded_describe(const Descriptor& desc, const std::string& label, const Trace& t, std::int64_t* cell,
                      double* values, std::size_t offspring) {
  const PluginCallScope scope(label, "describe()");
  try {
    desc.describe(&t, 1, cell, values);
  } catch (...) {
    throw EvaluationFault(label + " threw from describe(): " + what_of(std::current_exception()), offspring, offspring);
  }
}

RowEvaluator::RowEvaluator(const Environment& env, const Descriptor& desc, const PolicyShape& shape,
                           PluginLabels labels)
    : env_(env), desc_(desc), shape_(shape), labels_(std::move(labels)), dims_(desc.grid().dims()) {}

void RowEvaluator::run(const double* params, const std::uint64_t* seeds, std::size_t rows, double* records,
                       std::size_t first_row, std::atomic<std::uint64_t>* current) {
  if (traces_.size() < rows) traces_.resize(rows);
  for (std::size_t i = 0; i < rows; ++i) traces_[i].clear();
  // The environment reads the rows where they are (shared memory for worker processes): no copy.
  if (!current) {
    guarded_rollout(env_, labels_.environment, RolloutBatch{&shape_, params, seeds, 0, rows}, traces_.data(),
                    first_row);
  } else {
    for (std::size_t i = 0; i < rows; ++i) {
      current->store(progress_code(first_row + i, false), std::memory_order_relaxed);
      guarded_rollout(env_, labels_.environment, RolloutBatch{&shape_, params, seeds, i, i + 1}, traces_.data(),
                      first_row);
    }
  }
  const std::size_t w = record_width(dims_);
  for (std::size_t i = 0; i < rows; ++i) {
    double* r = records + i * w;
    const Trace& t = traces_[i];
    std::int64_t cell = -1;
    std::fill(r + kRecordHead, r + w, 0.0);
    if (t.status == EvalStatus::kOk) {
      if (current) current->store(progress_code(first_row + i, true), std::memory_order_relaxed);
      guarded_describe(desc_, labels_.descriptor, t, &cell, r + kRecordHead, first_row + i);
    }
    r[0] = static_cast<double>(static_cast<int>(t.status));
    r[1] = static_cast<double>(t.steps);
    r[2] = t.fitness;
    r[3] = static_cast<double>(cell);
  }
  if (current) current->store(0, std::memory_order_relaxed);
}

Evaluator::~Evaluator() = default;

ThreadEvaluator::ThreadEvaluator(const Environment& env, const Descriptor& desc, const PolicyShape& shape, int workers,
                                 PluginLabels labels, int persistent_worlds)
    : env_(env),
      desc_(desc),
      shape_(shape),
      labels_(std::move(labels)),
      dims_(desc.grid().dims()),
      worlds_(persistent_worlds),
      pool_(workers) {}

void ThreadEvaluator::evaluate_rows(const Matrix& params, const std::uint64_t* seeds, std::size_t begin,
                                    std::size_t end, Evaluations& out, int world) {
  RolloutBatch b;
  b.shape = &shape_;
  b.params = params.data();
  b.episode_seeds = seeds;
  b.begin = begin;
  b.end = end;
  b.world = world;
  for (std::size_t i = begin; i < end; ++i) traces_[i].clear();
  guarded_rollout(env_, labels_.environment, b, traces_.data(), 0);
  for (std::size_t i = begin; i < end; ++i) {
    const Trace& t = traces_[i];
    out.status[i] = t.status;
    out.steps[i] = t.steps;
    out.fitness[i] = t.fitness;
    if (t.status == EvalStatus::kOk)
      guarded_describe(desc_, labels_.descriptor, t, &out.cells[i],
                       out.descriptors.row(static_cast<Eigen::Index>(i)).data(), i);
  }
}

std::size_t ThreadEvaluator::begin_batch(const Matrix& params, const std::vector<std::uint64_t>& seeds,
                                         Evaluations& out) {
  const auto n = static_cast<std::size_t>(params.rows());
  QD_CHECK(seeds.size() == n, "one episode seed per row");
  out.reset(n, dims_);
  if (traces_.size() < n) traces_.resize(n);
  return n;
}

void ThreadEvaluator::evaluate(const Matrix& params, const std::vector<std::uint64_t>& seeds,
                               std::uint64_t first_episode, Evaluations& out) {
  const std::size_t n = begin_batch(params, seeds, out);
  if (worlds_ > 0) {
    // Episode e runs in world e mod N: row i's world is (first_episode + i) mod N, and a world's
    // rows run in order on whichever thread takes that world, so nothing depends on the threads.
    const auto worlds = static_cast<std::size_t>(worlds_);
    const std::size_t busy = std::min(worlds, n);
    pool_.run(busy, [&](std::size_t k) {
      const std::size_t world = (first_episode + k) % worlds;  // the world of row k, k < busy
      for (std::size_t i = k; i < n; i += worlds)
        evaluate_rows(params, seeds.data(), i, i + 1, out, static_cast<int>(world));
    });
    return;
  }
  // Chunks keep dispatch at one virtual call per chunk while leaving enough chunks for dynamic
  // load balancing; with one worker the whole batch is one call.
  const std::size_t workers = static_cast<std::size_t>(pool_.size());
  const std::size_t chunk = workers == 1 ? std::max<std::size_t>(n, 1) : std::max<std::size_t>(1, n / (workers * 8));
  const std::size_t chunks = (n + chunk - 1) / chunk;
  pool_.run(chunks, [&](std::size_t c) {
    const std::size_t begin = c * chunk;
    evaluate_rows(params, seeds.data(), begin, std::min(n, begin + chunk), out);
  });
}

std::string resolve_backend(const std::string& requested, int persistent_worlds) {
  if (requested != "auto") return requested;
  if (persistent_worlds > 0) return "threads";
  return mpi_active() ? "mpi" : "processes";
}

std::unique_ptr<Evaluator> make_evaluator(const EvaluatorSpec& spec, const Environment& env, const Descriptor& desc,
                                          const PolicyShape& shape) {
  const int worlds = spec.fresh_worlds ? 0 : env.info().persistent_worlds;
  const std::string backend = resolve_backend(spec.backend, worlds);
  if (worlds > 0 && backend != "threads")
    throw InputError("[evaluation] backend = \"" + backend + "\": " + spec.labels.environment + " keeps " +
                     std::to_string(worlds) +
                     " persistent worlds between episodes (one state per world, in episode order), which only "
                     "the \"threads\" backend runs; use backend = \"threads\" or \"auto\"");
  if (backend == "mpi") {
    if (!mpi_built())
      throw InputError(
          "[evaluation] backend = \"mpi\": this qdrun was built without MPI (configure with -DQD_WITH_MPI=ON)");
    if (!mpi_active())
      throw InputError("[evaluation] backend = \"mpi\" needs qdrun to be started by mpirun (mpirun -np N qdrun ...)");
    return make_mpi_evaluator(spec, env, desc, shape);
  }
  if (mpi_active() && mpi_size() > 1)
    throw InputError("[evaluation] backend = \"" + backend + "\" under mpirun with " + std::to_string(mpi_size()) +
                     " ranks: every rank would run the whole experiment; use backend = \"mpi\" (or \"auto\")");
  if (backend == "processes")
    return std::make_unique<ProcessEvaluator>(env, desc, shape, spec.workers, spec.capacity, spec.timeout_seconds,
                                              spec.labels);
  return std::make_unique<ThreadEvaluator>(env, desc, shape, spec.workers, spec.labels, worlds);
}

#ifndef QD_WITH_MPI
bool mpi_built() noexcept {
  return false;
}
bool mpi_launched() noexcept {
  return false;
}
void mpi_start(int*, char***) {}
bool mpi_active() noexcept {
  return false;
}
int mpi_rank() noexcept {
  return 0;
}
int mpi_size() noexcept {
  return 1;
}
bool mpi_workers_released() noexcept {
  return false;
}
void mpi_stop() noexcept {}
void mpi_abort(int code) noexcept {
  std::_Exit(code);
}
std::unique_ptr<Evaluator> make_mpi_evaluator(const EvaluatorSpec&, const Environment&, const Descriptor&,
                                              const PolicyShape&) {
  return nullptr;
}
#endif

}  // namespace qd::runtime
