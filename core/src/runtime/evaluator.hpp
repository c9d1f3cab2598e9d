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

#include <atomic>
#include <condition_variable>
#include <exception>
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

// The run failed during evaluation: a worker process or rank died or hung, or (rethrown by qdrun)
// a plugin broke its contract mid-run. The run stops, its last checkpoint stays valid; exit code 3.
class WorkerFailure : public Error {
 public:
  using Error::Error;
};

// A plugin failed on rows [first, last] of the batch being evaluated: rollout() or describe()
// threw, returned output that breaks the contract, or the worker process running it crashed,
// exited or hung. MapElites adds the loop and iteration and saves those offspring's parameters.
class EvaluationFault : public PluginError {
 public:
  EvaluationFault(const std::string& what, std::size_t first_row, std::size_t last_row)
      : PluginError(what), first(first_row), last(last_row) {}
  std::size_t first, last;
};

// How messages name the plugins an evaluator runs, e.g. "environment 'arm' (/path/qd_arm.so)".
struct PluginLabels {
  std::string environment = "the environment";
  std::string descriptor = "the descriptor";
};

// Rollouts of rows [b.begin, b.end). An exception becomes an EvaluationFault naming the environment
// and the offspring that throws, found by running the rows again one at a time (rollouts are
// deterministic and stateless); `offset` turns the rows of `b` into offspring indices.
void guarded_rollout(const Environment& env, const std::string& label, const RolloutBatch& b, Trace* traces,
                     std::size_t offset);
// describe() of one trace; an exception becomes an EvaluationFault naming the descriptor.
void guarded_describe(const Descriptor& desc, const std::string& label, const Trace& t, std::int64_t* cell,
                      double* values, std::size_t offspring);

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
  RowEvaluator(const Environment& env, const Descriptor& desc, const PolicyShape& shape, PluginLabels labels = {});
  std::size_t dims() const noexcept { return dims_; }
  // Rows [0, rows) of the row-major block `params` (rows × P) with their seeds -> rows records;
  // they are offspring first_row, first_row + 1, ... of the batch. With `current`, rows run one
  // rollout call each and `current` holds what runs (progress_code), so a supervisor can name the
  // offspring and the component that crashed or hung.
  void run(const double* params, const std::uint64_t* seeds, std::size_t rows, double* records,
           std::size_t first_row = 0, std::atomic<std::uint64_t>* current = nullptr);
  const PluginLabels& labels() const noexcept { return labels_; }

  // `current` while offspring `row` is in rollout() (describing = false) or describe(); 0 = idle.
  static std::uint64_t progress_code(std::size_t row, bool describing) { return 2 * (row + 1) + (describing ? 1 : 0); }

 private:
  const Environment& env_;
  const Descriptor& desc_;
  PolicyShape shape_;
  PluginLabels labels_;
  std::size_t dims_;
  std::vector<Trace> traces_;
};

class Evaluator {
 public:
  virtual ~Evaluator();
  virtual int workers() const noexcept = 0;
  virtual const char* backend() const noexcept = 0;
  // Row i of `params` is episode first_episode + i of the run (episodes counted from 0 over the
  // whole run, loop 0 included): that places it in its world when the environment keeps persistent
  // worlds; stateless environments ignore it.
  virtual void evaluate(const Matrix& params, const std::vector<std::uint64_t>& episode_seeds,
                        std::uint64_t first_episode, Evaluations& out) = 0;

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

// Serial (1 worker) or local threads. An environment with persistent worlds gets one row per call,
// each world's rows in order on one thread at a time, the worlds spread over the threads.
class ThreadEvaluator final : public Evaluator {
 public:
  // persistent_worlds: the environment's (info().persistent_worlds), or 0 to run every row as a
  // stateless rollout in a fresh world.
  ThreadEvaluator(const Environment& env, const Descriptor& desc, const PolicyShape& shape, int workers,
                  PluginLabels labels = {}, int persistent_worlds = 0);

  int workers() const noexcept override { return pool_.size(); }
  const char* backend() const noexcept override { return "threads"; }
  void evaluate(const Matrix& params, const std::vector<std::uint64_t>& episode_seeds, std::uint64_t first_episode,
                Evaluations& out) override;

 private:
  // Checks the seeds, sizes `out` and the trace scratch for the batch; returns its row count.
  std::size_t begin_batch(const Matrix& params, const std::vector<std::uint64_t>& seeds, Evaluations& out);
  // Rollouts and descriptors of rows [begin, end); `out` is already sized for the batch.
  void evaluate_rows(const Matrix& params, const std::uint64_t* seeds, std::size_t begin, std::size_t end,
                     Evaluations& out, int world = -1);
  const Environment& env_;
  const Descriptor& desc_;
  PolicyShape shape_;
  PluginLabels labels_;
  std::size_t dims_;
  int worlds_;                 // the environment's persistent worlds (0: stateless)
  std::vector<Trace> traces_;  // one per offspring, reused across batches
  WorkerPool pool_;
};

struct EvaluatorSpec {
  std::string backend = "auto";  // auto | threads | processes | mpi
  int workers = 1;               // local workers (threads/processes); MPI uses one per rank
  std::size_t capacity = 0;      // largest batch (rows) the process backend must hold
  double timeout_seconds = 0;    // a worker process silent this long in a batch is hung (0 = never); an MPI
                                 // rank, twice this plus 5 s (its own worker process is timed first)
  std::string status_file;       // written by the MPI backend when mpirun terminates the job
  PluginLabels labels;
  bool fresh_worlds = false;  // every episode in a fresh world, even where the environment keeps
                              // persistent ones (the dry-run's pilot): any backend may run them
};

// The backend "auto" resolves to mpi when launched by mpirun, else processes: supervised worker
// processes, one or more, so a crash, exit() or hang of plugin code never takes down the process
// that owns the run directory (and they are faster than threads for Box2D on this machine).
// "threads" runs rollouts inside qdrun (with one worker: serially, unsupervised). An environment
// with persistent worlds runs only with "threads" ("auto" resolves to it; `persistent_worlds` > 0).
std::string resolve_backend(const std::string& requested, int persistent_worlds = 0);
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
// Rank 0: the worker ranks were told to stop and will finalise MPI, so rank 0 may finalise too and
// end with its own exit code (after a plugin fault, say) instead of making mpirun end the job.
bool mpi_workers_released() noexcept;
void mpi_stop() noexcept;  // MPI_Finalize when initialised
[[noreturn]] void mpi_abort(int code) noexcept;
// Only with QD_WITH_MPI (make_evaluator checks mpi_built() first).
std::unique_ptr<Evaluator> make_mpi_evaluator(const EvaluatorSpec& spec, const Environment& env, const Descriptor& desc,
                                              const PolicyShape& shape);

}  // namespace qd::runtime
