// One run of an experiment: its components, archive, dataset and evaluator, the run directory
// and the checkpoint store, around the MAP-Elites loop (map_elites.hpp). A run starts fresh or
// resumes from its last checkpoint bit-identically.
#pragma once

#include "runtime/checkpoint.hpp"
#include "runtime/components.hpp"
#include "runtime/evaluator.hpp"
#include "runtime/experiment.hpp"
#include "runtime/grid_archive.hpp"
#include "runtime/map_elites.hpp"
#include "runtime/mpi_session.hpp"
#include "runtime/registry.hpp"
#include "runtime/run_directory.hpp"

#include <qd/dataset.hpp>

#include <exception>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>

namespace qd::runtime {

struct Progress {
  int loop = 0;
  int loops = 0;
  int iteration = 0;
  std::uint64_t evaluations = 0;
  std::uint64_t total_evaluations = 0;
  std::size_t elites = 0;
  double coverage = 0.0;
  double wall_seconds = 0.0;  // this session
  std::uint64_t session_evaluations = 0;
  bool loop_finished = false;
  std::string note;  // e.g. "training autoencoder"
};

// Keeps freed memory in the process instead of returning it to the kernel after every episode
// (glibc trims and unmaps eagerly; Box2D worlds and batch matrices are allocated over and over).
// Process-wide, so only executables call it (qdrun, benchmarks).
void tune_allocator();

struct RunOptions {
  int workers = 0;           // 0 = from the experiment (then all cores)
  int stop_after_loop = -1;  // stop cleanly after this loop's checkpoint (-1 = run to the end)
  std::string directory;     // run directory; empty = <output>/<name>/seed-<seed>
  std::string command_line;
  std::function<void(const Progress&)> on_progress;
  // Called once the run owns its directory (locked, checked, loaded), right before its status
  // becomes "running": from then on, whatever ends the run may write the status.
  std::function<void()> on_start;
};

class Run final : private LoopObserver, private TrainingLog {
 public:
  // Builds every component (plugin factories run here). Throws qd::InputError / ConfigError /
  // PluginError for bad input; creates nothing on disk.
  Run(Experiment experiment, const Registry& registry, RunOptions options);
  ~Run() override;
  Run(const Run&) = delete;
  Run& operator=(const Run&) = delete;

  const std::filesystem::path& directory() const noexcept { return dir_.path(); }
  const Experiment& experiment() const noexcept { return ex_; }

  // A fresh run directory (error if it already holds a run; the start of the same run that
  // stopped before its first checkpoint is started again: restarted()).
  void create_directory();
  // An existing run directory: loads its checkpoint and cuts the logs back to it. A run that
  // stopped before its first checkpoint has nothing to keep: it starts again (restarted()).
  void open_for_resume();
  // Whether create_directory() or open_for_resume() removed the start of a run that had no
  // checkpoint and started it again.
  bool restarted() const noexcept { return restarted_; }
  // Loads the checkpoint of an existing run directory without touching any file in it (for tools
  // that inspect a run, possibly while it is still running).
  void open_for_inspection();

  // Runs until the configured number of loops (or stop_after_loop). Returns true when finished.
  bool run();
  // MPI worker ranks instead of run(): evaluate what rank 0 sends until it stops the job.
  void serve() { evaluator_->serve(); }

  const Components& components() const noexcept { return c_; }
  const Archive& archive() const noexcept { return archive_; }
  const Dataset& dataset() const noexcept { return dataset_; }
  int workers() const noexcept { return evaluator_->workers(); }

 private:
  void iteration_done(const IterationOutcome& outcome) override;
  void training_started(int loop) override;
  void training_done(int loop, const FitReport& report, double seconds) override;
  TrainingLog* training_log() override { return this; }
  // TrainingLog: the representation's logs, kept by the run directory and cut back on resume.
  void append(const std::string& name, const std::string& header, const std::string& rows) override;
  // Writes fault-offspring.csv; returns its path, or "" when that fails.
  std::string fault_offspring(int loop, int iteration, std::size_t first, std::size_t last, const Matrix& theta,
                              const std::vector<std::uint64_t>& seeds) override;
  // Loads and verifies the checkpoint; `resuming` also checks the configuration against the
  // checkpoint's and cuts the logs back to it.
  void load_checkpoint(bool resuming);
  std::vector<std::string> log_names() const;
  void save_checkpoint(int loop);
  CheckpointStore::Components checkpointed_components() const;
  void write_provenance() const;
  // grid.toml, and a CVT's centroids.csv.
  void write_grid() const;
  void report(int loop, int iteration, bool loop_finished, const std::string& note = {});
  double wall_seconds() const;

  Experiment ex_;
  RunOptions opt_;
  Components c_;
  std::unique_ptr<Evaluator> evaluator_;
  Archive archive_;
  Dataset dataset_;
  RunDirectory dir_;
  CheckpointStore checkpoints_;
  MapElites loop_;

  int next_loop_ = 0;
  bool restarted_ = false;
  std::uint64_t session_first_evaluation_ = 0;
  double wall_before_ = 0.0;  // wall seconds of earlier sessions (resume)
  double train_seconds_ = 0.0;
  double session_start_ = 0.0;
  std::string metrics_row_;
  std::vector<std::string> training_logs_;  // the representation's logs, in the order first written
  std::exception_ptr log_failure_;          // a failed write to one of them
  bool resumed_ = false;                    // this session continues from a checkpoint
  // The mutator's kMixingRatio metric, written in metrics.csv's mixing_ratio column (npos: none).
  std::size_t mixing_metric_ = static_cast<std::size_t>(-1);
};

}  // namespace qd::runtime
