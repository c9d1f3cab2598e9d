// The checkpoint store: everything a run needs to continue bit-identically, written at every loop
// boundary and read back by --resume (and by tools that inspect a run).
//
// Files in the run directory:
//  * checkpoint.bin: the counters, the resolved configuration, the sizes of the appended logs,
//    the sizes of the two files below, and the state blobs of the representation, the mutator,
//    the initial sampler and (last, absent in checkpoints of earlier versions) the environment's
//    persistent worlds. Replaced atomically, so it is always a committed checkpoint.
//  * archive-state-NNNNN.bin: the archive as an append-only log of slot records; each checkpoint
//    appends the slots written since the previous one, and when more than half the log is stale a
//    new generation starts with one record per elite (the old file is removed once the checkpoint
//    that no longer needs it is committed).
//  * dataset.bin: the training dataset, append-only (it only grows).
// Appended bytes become durable before the checkpoint that counts them is committed; bytes past
// the committed sizes (from a checkpoint that never committed) are cut away by the next write or
// ignored by a load. Every appended chunk has a CRC-32C recorded in checkpoint.bin, and
// checkpoint.bin ends with the CRC-32C of the rest of it, so a load verifies every byte it uses
// and names the file and the byte range of any corruption.
//
// Writing happens on a background thread while the next loop runs (the loop only copies the
// changed records into a buffer): on Striker a checkpoint writes tens of megabytes per loop.
#pragma once

#include "runtime/grid_archive.hpp"

#include <qd/dataset.hpp>
#include <qd/environment.hpp>
#include <qd/mutator.hpp>
#include <qd/representation.hpp>

#include <condition_variable>
#include <cstdint>
#include <exception>
#include <filesystem>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace qd::runtime {

// CRC-32C (Castagnoli, as in iSCSI and ext4) of size bytes; with `previous`, the CRC-32C of the
// bytes that `previous` is the CRC-32C of, followed by these.
std::uint32_t crc32c(const char* bytes, std::size_t size, std::uint32_t previous = 0);

struct CheckpointCounters {
  int loop = -1;  // the last loop the checkpoint completes
  std::uint64_t evaluations = 0;
  double wall_seconds = 0.0;
  double train_seconds = 0.0;
};

// A log file the run appends to, its size at the checkpoint and the CRC-32C of those bytes
// (`checksummed` is false in a checkpoint written before qdrun recorded them: only the size is
// checked then).
struct LogSize {
  std::string name;
  std::uint64_t size = 0;
  std::uint32_t crc = 0;
  bool checksummed = true;
  bool operator<(const LogSize& other) const { return name < other.name; }
};

class CheckpointStore {
 public:
  // One appended piece of an append-only file: it ends at `end` (its start is the previous
  // chunk's end, or 0) and has this CRC-32C.
  struct Chunk {
    std::uint64_t end;
    std::uint32_t crc;
  };

  // The components whose state a checkpoint carries. The environment's, only when it keeps
  // persistent worlds (null otherwise).
  struct Components {
    Representation* representation;
    Mutator* mutator;
    Mutator* initial;
    Environment* environment = nullptr;
  };

  CheckpointStore(std::filesystem::path dir, std::size_t param_count, std::size_t descriptor_dims);
  ~CheckpointStore();  // waits for the checkpoint in flight (a write error is lost: call wait() first)
  CheckpointStore(const CheckpointStore&) = delete;
  CheckpointStore& operator=(const CheckpointStore&) = delete;

  static bool exists(const std::filesystem::path& dir);

  // Queues a checkpoint of this state; waits for the previous one first and rethrows its error.
  // An environment with persistent worlds is then reloaded from the state just saved, so that the
  // run continues from exactly what a resume of this checkpoint would rebuild.
  void save(const CheckpointCounters& counters, const std::string& config, const std::vector<LogSize>& logs,
            Archive& archive, const Dataset& dataset, const Components& components);
  // Waits until the checkpoint in flight is committed; rethrows its write error.
  void wait();

  // Loads the committed checkpoint into the given objects (archive and dataset of the right
  // shape). With `tidy`, files of a never-committed archive generation are removed. Throws
  // StateError naming the file.
  struct Loaded {
    CheckpointCounters counters;
    std::string config;
    std::vector<LogSize> logs;
  };
  Loaded load(Archive& archive, Dataset& dataset, const Components& components, bool tidy);

 private:
  struct Append {
    std::filesystem::path path;
    std::uint64_t offset = 0;  // the file's committed size; anything past it is cut first
    std::string bytes;
  };
  struct Job {
    std::vector<Append> appends;
    std::string checkpoint;
    std::vector<std::filesystem::path> remove_after;
  };
  void write(const Job& job) const;
  void work();
  std::thread start_writer();  // the thread that runs work(); SystemError when none can be had
  std::filesystem::path archive_log(std::uint64_t generation) const;
  void load_archive(Archive& archive, std::uint64_t slots, bool tidy);
  void load_dataset(Dataset& dataset, std::uint64_t rows);

  std::filesystem::path dir_;
  std::size_t param_count_, dims_;
  std::uint64_t archive_generation_ = 0;
  std::vector<Chunk> archive_chunks_;  // of the current generation, committed or in flight
  std::vector<Chunk> dataset_chunks_;
  std::size_t dataset_rows_ = 0;
  std::vector<std::size_t> dirty_;

  std::mutex mutex_;
  std::condition_variable wake_, idle_;
  Job job_;
  bool pending_ = false, stop_ = false;
  std::exception_ptr error_;
  std::thread thread_;  // last: started once the members it uses exist
};

}  // namespace qd::runtime
