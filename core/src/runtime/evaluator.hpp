// Evaluation: the interface the loop uses to run rollouts and descriptors for a batch, and its
// factory. The rooms of the evaluation wing (docs/design.md, "Evaluation, loop and run directory"):
//   evaluator.hpp           this interface, the faults, the factory (evaluator_factory.cpp)
//   batch_protocol.hpp      the one row evaluator every backend calls, the packed records, chunking
//   thread_evaluator.hpp    backend "threads" (serial or local threads), on worker_pool.hpp
//   process_evaluator.hpp   backend "processes": supervised worker processes (the default)
//   mpi_evaluator.cpp       backend "mpi": ranks, each with one worker process (QD_WITH_MPI)
//   mpi_session.hpp         MPI start, rank, size and stop; rank 0's report when mpirun ends the job
//
// Determinism: every result is written into its own slot (indexed by offspring), and nothing in a
// rollout depends on which thread, process or rank runs it, so every backend and worker count gives
// identical results.
#pragma once

#include "runtime/backend.hpp"

#include <qd/descriptor.hpp>
#include <qd/environment.hpp>
#include <qd/errors.hpp>
#include <qd/policy.hpp>
#include <qd/types.hpp>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
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

struct EvaluatorSpec {
  Backend backend = Backend::kAuto;
  int workers = 1;             // local workers (threads/processes); MPI uses one per rank
  std::size_t capacity = 0;    // largest batch (rows) the process backend must hold
  double timeout_seconds = 0;  // a worker process silent this long in a batch is hung (0 = never); an MPI
                               // rank, twice this plus 5 s (its own worker process is timed first)
  std::string status_file;     // written by the MPI backend when mpirun terminates the job
  PluginLabels labels;
  bool fresh_worlds = false;  // every episode in a fresh world, even where the environment keeps
                              // persistent ones (the dry-run's pilot): any backend may run them
};

// The backend "auto" resolves to mpi when launched by mpirun, else processes: supervised worker
// processes, one or more, so a crash, exit() or hang of plugin code never takes down the process
// that owns the run directory (and they are faster than threads for Box2D on this machine).
// "threads" runs rollouts inside qdrun (with one worker: serially, unsupervised). An environment
// with persistent worlds runs only with "threads" ("auto" resolves to it; `persistent_worlds` > 0).
Backend resolve_backend(Backend requested, int persistent_worlds = 0);
std::unique_ptr<Evaluator> make_evaluator(const EvaluatorSpec& spec, const Environment& env, const Descriptor& desc,
                                          const PolicyShape& shape);

// Number of hardware threads (at least 1).
int hardware_workers();

}  // namespace qd::runtime
