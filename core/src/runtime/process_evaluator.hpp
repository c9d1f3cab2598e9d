// Local worker processes: forked once after setup (plugins loaded, components built), so each has
// its own copy of the environment and of Box2D's unsynchronised global counters, which make threads
// scale badly (docs/user-guide.md, "Parallel evaluation"). The parameter batch, the episode seeds and the
// per-offspring result records live in one shared anonymous mapping; workers claim chunks of rows
// from an atomic counter there (dynamic load balancing).
//
// The parent only supervises: no rollout runs in the process that owns the run directory, so a
// rollout that crashes, aborts, calls exit() or hangs is observed and named instead of taking the
// run down with it (issue 20). Each worker publishes the offspring it is evaluating (rollout or
// describe) in the mapping and has a socket pair to the parent: one byte starts a batch, one byte
// reports it done. End of file on that socket means the worker ended; no progress for
// timeout_seconds means it hung. Either ends the batch with an EvaluationFault naming the worker,
// the component and the offspring (a WorkerFailure when the worker was between offspring).
//
// The MPI backend gives every rank one such worker process (evaluate_rows), so no rollout runs in
// an MPI process either. The child never calls MPI; an exit() in plugin code ends it without
// running the parent's exit handlers (which include MPI's and the run's), and a crash takes the
// signal's default action, not a handler the parent installed (MPI prints backtraces).
#pragma once

#include "runtime/batch_protocol.hpp"
#include "runtime/evaluator.hpp"

#include <sys/types.h>

namespace qd::runtime {

class ProcessEvaluator final : public Evaluator {
 public:
  // workers >= 1 forked processes; capacity: most rows per batch. `where` prefixes the messages
  // that name a worker process (under MPI: "MPI rank 1 on node7: ").
  ProcessEvaluator(const Environment& env, const Descriptor& desc, const PolicyShape& shape, int workers,
                   std::size_t capacity, double timeout_seconds, PluginLabels labels = {}, std::string where = "");
  ~ProcessEvaluator() override;
  ProcessEvaluator(const ProcessEvaluator&) = delete;
  ProcessEvaluator& operator=(const ProcessEvaluator&) = delete;

  int workers() const noexcept override { return static_cast<int>(children_.size()); }
  const char* backend() const noexcept override { return "processes"; }
  void evaluate(const Matrix& params, const std::vector<std::uint64_t>& episode_seeds, std::uint64_t first_episode,
                Evaluations& out) override;
  // Rows [0, rows) of the row-major block `params` (rows x P) with their seeds -> rows packed records
  // (record_width); they are offspring first_row, first_row + 1, ... of the batch, which is how a
  // fault names them. Same faults as evaluate().
  void evaluate_rows(const double* params, const std::uint64_t* seeds, std::size_t rows, double* records,
                     std::size_t first_row);

  // For tests: the pid of worker process w (1-based).
  pid_t worker_pid(int w) const { return children_.at(static_cast<std::size_t>(w - 1)).pid; }

 private:
  struct Control;
  struct Child {
    pid_t pid = -1;
    int fd = -1;  // parent's end of the socket pair
  };
  [[noreturn]] void child_main(int w, int fd);
  void work(int w, RowEvaluator& ev);
  // Runs `rows` rows through the workers; their records stay in shared memory. The rows are copied
  // into shared memory while the workers already evaluate the first ones.
  void run_batch(const double* params, const std::uint64_t* seeds, std::size_t rows, std::size_t first_row);
  // Ends the workers and throws: an EvaluationFault when `current` (RowEvaluator::progress_code)
  // names the offspring the worker was on, else a WorkerFailure.
  [[noreturn]] void fail(const std::string& message, std::uint64_t current = 0);
  // " in rollout() of environment 'x' (library)" for a progress code, "" for 0.
  std::string doing(std::uint64_t current) const;
  void shut_down() noexcept;

  std::size_t P_, dims_, width_, capacity_;
  double timeout_;
  RowEvaluator own_;
  std::string where_;
  void* map_ = nullptr;
  std::size_t map_bytes_ = 0;
  Control* ctl_ = nullptr;
  double* params_ = nullptr;
  std::uint64_t* seeds_ = nullptr;
  double* records_ = nullptr;
  std::vector<Child> children_;
  bool broken_ = false;
};

}  // namespace qd::runtime
