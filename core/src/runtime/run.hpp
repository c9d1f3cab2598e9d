// One run of an experiment: builds the components, owns the run directory, runs the loop of
// spec section 3 with checkpoints at every loop boundary, and resumes from them bit-identically.
#pragma once

#include "runtime/checkpoint_writer.hpp"
#include "runtime/csv.hpp"
#include "runtime/evaluator.hpp"
#include "runtime/experiment.hpp"
#include "runtime/registry.hpp"
#include "runtime/row_copier.hpp"

#include <qd/archive.hpp>
#include <qd/dataset.hpp>
#include <qd/descriptor.hpp>
#include <qd/environment.hpp>
#include <qd/mutator.hpp>
#include <qd/representation.hpp>

#include <cstdlib>
#include <filesystem>
#include <functional>
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
  std::string backend;       // empty = from the experiment
  int stop_after_loop = -1;  // stop cleanly after this loop's checkpoint (-1 = run to the end)
  std::string directory;     // run directory; empty = <output>/<name>/seed-<seed>
  std::string command_line;
  std::function<void(const Progress&)> on_progress;
};

class Run {
 public:
  // Builds every component (plugin factories run here). Throws qd::InputError / ConfigError /
  // PluginError for bad input; creates nothing on disk.
  Run(Experiment experiment, const Registry& registry, RunOptions options);
  ~Run();

  // The run directory <output>/<name>/seed-<seed>.
  const std::filesystem::path& directory() const noexcept { return dir_; }
  const Experiment& experiment() const noexcept { return ex_; }

  // Creates a fresh run directory (error if it already holds a run), or opens an existing one and
  // loads its checkpoint.
  void create_directory();
  void open_for_resume();
  // Loads the checkpoint of an existing run directory without touching any file in it (for
  // tools that inspect a run, possibly while it is still running).
  void open_for_inspection();

  // Runs until the configured number of loops (or stop_after_loop). Returns true when finished.
  bool run();
  // MPI worker ranks instead of run(): evaluate what rank 0 sends until it stops the job.
  void serve();
  const Evaluator& evaluator() const { return *evaluator_; }

  // Re-runs the elite of `cell` from the run directory's archive.csv and draws it to `svg`.
  // Returns the replayed trace (its status tells whether it still evaluates as stored).
  Trace replay(std::int64_t cell, const std::filesystem::path& svg) const;

  // Re-runs every elite of archive.csv (on the run's workers) and writes their `main` trajectory
  // rows to `csv`: cell,landed,status,row,main_0,... (`landed` = the cell the replay falls in).
  // Returns how many elites replayed into their stored cell.
  struct ReplayAllResult {
    std::size_t elites = 0, as_stored = 0;
  };
  ReplayAllResult replay_all(const std::filesystem::path& csv);

  // Writes the latent code of every dataset entry under the loaded representation to `csv`:
  // cell,loop,z_0,... (`loop` = the loop the entry joined the dataset). Needs a checkpoint
  // (open_for_inspection) and a representation with a latent space.
  void write_latents(const std::filesystem::path& csv) const;

  // Accessors for tests and tools.
  const Archive& archive() const { return *archive_; }
  const Dataset& dataset() const { return *dataset_; }
  const Environment& environment() const { return *env_; }
  const Descriptor& descriptor() const { return *desc_; }
  const PolicyShape& policy_shape() const { return shape_; }
  // Whether the MAP-Elites loop uses one offspring buffer, streamed, or two ([evaluation]
  // offspring_buffers; decided once, at construction).
  bool one_offspring_buffer() const { return one_buffer_; }
  // Whether the background writer is still writing the last loop's checkpoint (benchmarks use it
  // to keep their own work from overlapping the run's disk writes).
  bool checkpoint_in_flight() const { return checkpoint_writer_ && checkpoint_writer_->busy(); }

 private:
  void loop_zero();
  void map_elites_loop(int loop);
  void fit_representation(int loop);
  bool choose_one_offspring_buffer() const;
  void fill_reconstruction(Offspring& off, Vector& recn) const;
  void write_metrics_row(int loop, int iteration, const Offspring* off, std::size_t added, std::size_t replaced,
                         std::size_t invalid);
  void write_checkpoint(int loop);
  void load_checkpoint(bool cut_logs);
  void load_dataset(std::uint64_t rows);
  void load_archive(std::uint64_t generation, std::uint64_t bytes, std::uint64_t slots, bool remove_stale);
  std::filesystem::path archive_log_path(std::uint64_t generation) const;
  void finish_checkpoints();  // waits for the checkpoint in flight; rethrows its write error
  void write_snapshot(const std::filesystem::path& path) const;
  void write_provenance() const;
  void set_status(const std::string& status) const;
  void report(int loop, int iteration, bool loop_finished, const std::string& note = {});
  double wall_seconds() const;

  Experiment ex_;
  RunOptions opt_;
  std::filesystem::path dir_;
  PolicyShape shape_;
  Owned<Environment> env_;
  Owned<Descriptor> desc_;
  Owned<Representation> repr_;
  Owned<Mutator> mutator_;
  Owned<Mutator> initial_;
  std::unique_ptr<Evaluator> evaluator_;
  std::unique_ptr<Archive> archive_;
  std::unique_ptr<Dataset> dataset_;
  std::vector<std::string> plugin_lines_;
  std::vector<std::string> mutator_metric_names_;
  AppendLog metrics_log_;               // metrics.csv, one row per iteration
  std::filesystem::path metrics_path_;  // <dir>/metrics.csv
  std::string metrics_row_;
  bool one_buffer_ = false;  // see choose_one_offspring_buffer

  // Batch buffers reused across iterations and loops: fresh multi-megabyte allocations every loop
  // cost page faults that showed up as framework overhead.
  Parents parents_;
  Offspring offspring_[2];  // alternate batches unless the evaluator streams rows (see map_elites_loop)
  Vector recn_;
  Evaluations evaluations_buffer_;
  std::vector<std::uint64_t> seeds_;
  std::vector<Insertion> outcomes_;

  // Checkpoints: written by a background thread. The archive and the dataset go to append-only
  // files; the last submitted checkpoint covers their first *_bytes_saved_ bytes.
  CheckpointWriter::Job checkpoint_job_;
  std::vector<std::size_t> dirty_slots_;
  std::vector<std::size_t> all_slots_;  // the capture list of a compaction
  struct FreeBuffer {
    void operator()(char* p) const { std::free(p); }
  };
  // The archive records of the checkpoint in flight, after room for a generation's header;
  // aligned for O_DIRECT (CheckpointWriter::Append::direct).
  std::unique_ptr<char, FreeBuffer> capture_buffer_;
  std::size_t capture_capacity_ = 0;
  std::uint64_t archive_generation_ = 0;
  std::uint64_t archive_bytes_saved_ = 0;
  std::size_t dataset_rows_saved_ = 0;
  std::uint64_t dataset_bytes_saved_ = 0;
  std::unique_ptr<CheckpointWriter> checkpoint_writer_;
  // Last: destroyed first, completing copies that read offspring_ rows.
  std::vector<Archive::DeferredCopy> copies_;
  std::unique_ptr<RowCopier> row_copier_;

  int next_loop_ = 0;
  std::uint64_t evaluations_ = 0;
  std::uint64_t session_evaluations_ = 0;
  double wall_before_ = 0.0;  // wall seconds of earlier sessions (resume)
  double train_seconds_ = 0.0;
  double session_start_ = 0.0;
};

}  // namespace qd::runtime
