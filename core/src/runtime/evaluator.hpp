// Runs rollouts and descriptors for a batch: the abstract interface the loop uses, and its
// backends (serial / local threads here; local processes in process_evaluator.hpp; MPI ranks in
// mpi_evaluator.cpp when built with QD_WITH_MPI).
//
// Determinism: every result is written into its own slot (indexed by offspring), and nothing in a
// rollout depends on which thread, process or rank runs it, so every backend and worker count gives
// identical results.
#pragma once

#include <qd/descriptor.hpp>
#include <qd/environment.hpp>
#include <qd/errors.hpp>
#include <qd/policy.hpp>
#include <qd/types.hpp>

#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace qd::runtime {

// What the loop reads of an evaluation: compact per-offspring fields, so remote workers only send
// these back (the trace stays where the rollout ran).
struct Evaluations {
  std::vector<EvalStatus> status;
  std::vector<std::int32_t> steps;
  std::vector<double> fitness;
  std::vector<std::int64_t> cells;  // -1 = not insertable (failed or undescribable)
  Matrix descriptors;               // n × dims

  void reset(std::size_t n, std::size_t dims);
};

// A worker process or rank died or hung: the run stops, its last checkpoint stays valid.
class WorkerFailure : public Error {
 public:
  using Error::Error;
};

// Packed per-offspring record used by the process and MPI backends: status, steps, fitness, cell,
// then the descriptor values, all as doubles (status, steps and cell are small integers, exact).
constexpr std::size_t kRecordHead = 4;
inline std::size_t record_width(std::size_t dims) {
  return kRecordHead + dims;
}
void unpack_records(const double* records, std::size_t begin, std::size_t end, std::size_t dims, Evaluations& out);

// Guided self-scheduling for the process and MPI backends: a share of the rows still unclaimed,
// at most `largest`, at least 1, so chunks shrink towards the end of a batch and no worker is left
// running a long last chunk while the others idle.
inline std::size_t guided_chunk(std::size_t remaining, std::size_t workers, std::size_t largest) {
  const std::size_t share = remaining / (4 * workers);
  return share < 1 ? 1 : (share > largest ? largest : share);
}
inline std::size_t largest_chunk(std::size_t n, std::size_t workers) {
  return n / (workers * 8) < 1 ? 1 : n / (workers * 8);
}

// Evaluates rows of a parameter block into packed records; owns its trace scratch (one per worker).
class RowEvaluator {
 public:
  RowEvaluator(const Environment& env, const Descriptor& desc, const PolicyShape& shape);
  std::size_t dims() const noexcept { return dims_; }
  // Rows [0, rows) of the row-major block `params` (rows × P) with their seeds -> rows records.
  void run(const double* params, const std::uint64_t* seeds, std::size_t rows, double* records);

 private:
  const Environment& env_;
  const Descriptor& desc_;
  PolicyShape shape_;
  std::size_t dims_;
  Matrix block_;
  std::vector<Trace> traces_;
};

class Evaluator {
 public:
  virtual ~Evaluator();
  virtual int workers() const noexcept = 0;
  virtual const char* backend() const noexcept = 0;
  virtual void evaluate(const Matrix& params, const std::vector<std::uint64_t>& episode_seeds, Evaluations& out) = 0;

  // MPI worker ranks: serve rank 0 until it stops the job. Other backends have no remote side.
  virtual void serve() {}
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
  void stop();  // ends and joins the threads
  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  const std::function<void(std::size_t)>* job_ = nullptr;
  std::size_t n_ = 0, next_ = 0, finished_ = 0;
  std::uint64_t generation_ = 0;
  int busy_ = 0;
  bool stop_ = false;
};

// Serial (1 worker) or local threads.
class ThreadEvaluator final : public Evaluator {
 public:
  ThreadEvaluator(const Environment& env, const Descriptor& desc, const PolicyShape& shape, int workers);

  int workers() const noexcept override { return pool_.size(); }
  const char* backend() const noexcept override { return "threads"; }
  void evaluate(const Matrix& params, const std::vector<std::uint64_t>& episode_seeds, Evaluations& out) override;

 private:
  // Checks the seeds, sizes `out` and the trace scratch for the batch; returns its row count.
  std::size_t begin_batch(const Matrix& params, const std::vector<std::uint64_t>& seeds, Evaluations& out);
  // Rollouts and descriptors of rows [begin, end); `out` is already sized for the batch.
  void evaluate_rows(const Matrix& params, const std::uint64_t* seeds, std::size_t begin, std::size_t end,
                     Evaluations& out);
  const Environment& env_;
  const Descriptor& desc_;
  PolicyShape shape_;
  std::size_t dims_;
  std::vector<Trace> traces_;  // one per offspring, reused across batches
  WorkerPool pool_;
};

struct EvaluatorSpec {
  std::string backend = "auto";  // auto | threads | processes | mpi
  int workers = 1;               // local workers (threads/processes); MPI uses one per rank
  std::size_t capacity = 0;      // largest batch (rows) the process backend must hold
  double timeout_seconds = 0;    // a worker process/rank silent this long in a batch is hung (0 = never)
  std::string status_file;       // written by the MPI backend when mpirun terminates the job
};

// The backend "auto" resolves to: mpi when launched by mpirun, else processes with > 1 worker
// (faster than threads for Box2D on this machine, see README), else serial.
std::string resolve_backend(const std::string& requested, int workers);
std::unique_ptr<Evaluator> make_evaluator(const EvaluatorSpec& spec, const Environment& env, const Descriptor& desc,
                                          const PolicyShape& shape);

// Number of hardware threads (at least 1).
int hardware_workers();

// MPI session helpers; without QD_WITH_MPI they report a single process and mpi_start() is a no-op.
bool mpi_built() noexcept;
bool mpi_launched() noexcept;             // started by mpirun/mpiexec (environment variables)
void mpi_start(int* argc, char*** argv);  // MPI_Init when launched, else nothing
bool mpi_active() noexcept;               // MPI initialised
int mpi_rank() noexcept;
int mpi_size() noexcept;
void mpi_stop() noexcept;  // MPI_Finalize when initialised
[[noreturn]] void mpi_abort(int code) noexcept;
// Only with QD_WITH_MPI (make_evaluator checks mpi_built() first).
std::unique_ptr<Evaluator> make_mpi_evaluator(const EvaluatorSpec& spec, const Environment& env, const Descriptor& desc,
                                              const PolicyShape& shape);

}  // namespace qd::runtime
