// The run directory <output>/<name>/seed-<seed>: the files a run writes besides its checkpoint.
//   config.toml        the resolved configuration
//   grid.toml          the descriptor's grid (how a cell index decomposes), for plots
//   provenance*.toml   who, where and with what it ran (one file per session)
//   status             running | complete | stopped ... | failed: ...
//   metrics.csv        one row per iteration; training.csv one row per loop (appended logs)
//   archive.csv, archive/loop-NNNNN.csv   the final archive and snapshots
#pragma once

#include "runtime/checkpoint.hpp"
#include "runtime/run_files.hpp"

#include <filesystem>
#include <string>
#include <vector>

namespace qd::runtime {

// The provenance file of the session of `dir`'s run that ran loop `loop`: the
// provenance-resume-loop-L.toml with the highest L <= loop, else provenance.toml (the first
// session's). A large `loop` gives the newest session's.
std::filesystem::path session_provenance(const std::filesystem::path& dir, int loop);

// What a run directory without a checkpoint holds.
enum class Leftover {
  kNone,             // no run (no config.toml and nothing of a run's results)
  kUnfinishedStart,  // a run that stopped before its first checkpoint: a restart loses nothing
  kResults,          // results without a checkpoint: never deleted, never resumed
};

// Whether `name` may be a representation's training log (TrainingLog::append): a plain file name
// ending in ".csv", none of the run's own files.
bool is_training_log_name(const std::string& name);

class RunDirectory {
 public:
  explicit RunDirectory(std::filesystem::path dir);
  ~RunDirectory();
  RunDirectory(const RunDirectory&) = delete;
  RunDirectory& operator=(const RunDirectory&) = delete;

  const std::filesystem::path& path() const noexcept { return dir_; }

  // A fresh run: creates the directory, takes its lock and writes the config and the headers of
  // the logs (the caller writes the status). An error if the directory holds a run with a
  // checkpoint or results; the start of a run of the same configuration (`config`, compared as
  // --resume would) that stopped before its first checkpoint is removed and started again: returns
  // true then.
  bool create(const std::string& config, const std::string& metrics_header);
  // An existing run to continue: takes its lock; error if the directory is not writable.
  void open();

  // One owner per run directory, held until this object is destroyed or the process ends: a
  // flock on the directory itself (a user cannot delete it while it holds the run, and a
  // hard-linked copy of the run is another directory), and one on <dir>/lock, which names the
  // holder (pid and host) and is what older qdrun versions look at. Where the file system cannot
  // lock a directory (NFS), the lock file alone. Throws InputError naming the holder.
  void lock();
  // Who holds the lock of `dir` ("pid N on host H"), or "" when nobody does.
  static std::string holder(const std::filesystem::path& dir);

  // What `dir` holds besides a checkpoint; `found` gets a description of the results (for the
  // messages: "metrics.csv holds loops up to 3, archive.csv").
  static Leftover leftover(const std::filesystem::path& dir, std::string* found = nullptr);
  // The text of `dir`/status ("" when there is none); InputError when it is not a regular file.
  static std::string read_status(const std::filesystem::path& dir);

  void write_config(const std::string& config) const;
  // Replaces the file `name` in the run directory atomically.
  void write(const std::string& name, const std::string& text) const;
  // provenance.toml for the session that starts at loop 0, provenance-resume-loop-L.toml else.
  void write_provenance(int first_loop, const std::string& text) const;
  void set_status(const std::string& status) const;

  void append_metrics(const std::string& row) { metrics_.append(row); }
  void append_training(const std::string& row) { training_.append(row); }
  // Appends `rows` to the representation's log `name` (is_training_log_name), `header` first when
  // the log is new or empty; `restart` removes a file of that name first. SystemError when the
  // write fails.
  void append_log(const std::string& name, const std::string& header, const std::string& rows, bool restart);

  // The sizes and CRC-32C of the logs the run appends to (`names`: metrics.csv, training.csv and
  // the representation's), those that exist, for a checkpoint. Each log is made private first
  // (open_for_update), so neither this run nor its representation appends into a file another
  // directory shares. The checksums extend those of the previous call by the bytes added since.
  std::vector<LogSize> log_sizes(const std::vector<std::string>& names);
  // Cuts the logs back to the sizes a checkpoint recorded and checks their checksums, and removes a
  // log of `names` that the checkpoint does not know (written after it). Throws StateError when a
  // recorded log is missing, shorter than recorded or edited. Touches no other file.
  void cut_logs(const std::vector<LogSize>& sizes, const std::vector<std::string>& names);
  // Lines in a file of the run directory (0 if it does not exist).
  std::size_t count_lines(const std::string& name) const;

 private:
  void check_writable() const;
  // Removes what a run that stopped before its first checkpoint wrote, and nothing else (a
  // user's notes stay). Only under this directory's lock: another qdrun's files are not ours.
  static void remove_unfinished_start(const std::filesystem::path& dir);

  std::filesystem::path dir_;
  AppendLog metrics_, training_;
  int lock_fd_ = -1, dir_fd_ = -1;
  std::vector<LogSize> checksummed_;  // what log_sizes() has read of each log so far
};

}  // namespace qd::runtime
