#include "runtime/checkpoint.hpp"

#include "runtime/run_files.hpp"

#include <qd/errors.hpp>
#include <qd/state_io.hpp>

#include <boost/crc.hpp>

#if defined(__SSE4_2__)
#include <nmmintrin.h>
#endif
#include <fcntl.h>
#include <pthread.h>
#include <unistd.h>
#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <numeric>
#include <sstream>
#include <system_error>

namespace qd::runtime {
namespace fs = std::filesystem;

// With SSE4.2 (every x86-64-v2 CPU) the CPU's crc32 instruction: Boost's table-driven CRC runs at
// about 0.4 GB/s, which cost 1-2 % of a Striker ps-uniform run (a checkpoint of megabytes every
// 0.4 s); the instruction about 8.7 GB/s (docs/performance-history.md). Both give the same checksum.
std::uint32_t crc32c(const char* bytes, std::size_t size, std::uint32_t previous) {
#if defined(__SSE4_2__)
  std::uint64_t crc = previous ^ 0xFFFFFFFFu;
  for (; size >= 8; size -= 8, bytes += 8) {
    std::uint64_t word;
    std::memcpy(&word, bytes, 8);
    crc = _mm_crc32_u64(crc, word);
  }
  auto crc32 = static_cast<std::uint32_t>(crc);
  for (; size > 0; --size, ++bytes) crc32 = _mm_crc32_u8(crc32, static_cast<std::uint8_t>(*bytes));
  return crc32 ^ 0xFFFFFFFFu;
#else
  boost::crc_optimal<32, 0x1EDC6F41, 0xFFFFFFFF, 0xFFFFFFFF, true, true> crc(previous ^ 0xFFFFFFFFu);
  crc.process_bytes(bytes, size);
  return crc.checksum();
#endif
}

namespace {
// Version 04 records the CRC-32C of each log next to its size; 03 (qdrun before it) is still read.
constexpr char kCheckpointMagic[8] = {'Q', 'D', 'C', 'K', 'P', 'T', '0', '4'};
constexpr char kCheckpointMagic03[8] = {'Q', 'D', 'C', 'K', 'P', 'T', '0', '3'};
// The most a checkpoint can hold: its configuration and three state blobs of at most 1 GiB each
// (state::read_string), counters and chunk lists.
constexpr std::uint64_t kMaxCheckpointBytes = std::uint64_t{5} << 30;
constexpr char kArchiveLogMagic[8] = {'Q', 'D', 'A', 'R', 'L', 'G', '0', '1'};
constexpr char kDatasetMagic[8] = {'Q', 'D', 'D', 'S', 'E', 'T', '0', '1'};
constexpr const char* kCheckpointFile = "checkpoint.bin";
constexpr const char* kDatasetFile = "dataset.bin";
// Both append-only files start with their magic and the shape: P (and the descriptor dims).
constexpr std::uint64_t kArchiveHeaderBytes = sizeof(kArchiveLogMagic) + 2 * sizeof(std::uint64_t);
constexpr std::uint64_t kDatasetHeaderBytes = sizeof(kDatasetMagic) + sizeof(std::uint64_t);

// An archive record: slot, cell (int64), fitness, recn error, descriptor, parameters (doubles),
// native byte order.
std::size_t record_bytes(std::size_t P, std::size_t dims) {
  return 4 * 8 + (dims + P) * 8;
}
// A dataset row: cell, loop (int64), parameters (doubles).
std::size_t dataset_row_bytes(std::size_t P) {
  return 2 * 8 + P * 8;
}

template <class T>
void append_raw(std::string& out, const T& v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof(T));
}

void append_record(std::string& out, const Archive& a, std::size_t slot) {
  append_raw(out, static_cast<std::int64_t>(slot));
  append_raw(out, a.cell(slot));
  append_raw(out, a.fitness(slot));
  append_raw(out, a.recn_error(slot));
  out.append(reinterpret_cast<const char*>(a.descriptor(slot)), a.descriptor_dims() * sizeof(double));
  out.append(reinterpret_cast<const char*>(a.params(slot)), a.param_count() * sizeof(double));
}

struct Fd {
  int fd;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

template <class Component>
std::string blob_of(const Component& component) {
  std::ostringstream o(std::ios::binary);
  component.save(o);
  return o.str();
}
}  // namespace

CheckpointStore::CheckpointStore(fs::path dir, std::size_t param_count, std::size_t descriptor_dims)
    : dir_(std::move(dir)), param_count_(param_count), dims_(descriptor_dims), thread_(start_writer()) {}

std::thread CheckpointStore::start_writer() {
  try {
    return std::thread([this] { work(); });
  } catch (const std::system_error& e) {
    // A thread limit (ulimit -u, a container's pids.max) or no memory for its stack (ulimit -v).
    throw SystemError(std::string("cannot start the checkpoint writer thread: ") + e.what());
  }
}

CheckpointStore::~CheckpointStore() {
  {
    std::unique_lock<std::mutex> lock(mutex_);
    idle_.wait(lock, [&] { return !pending_; });
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

bool CheckpointStore::exists(const fs::path& dir) {
  // A symlink counts (and is refused when read): never taken for a run without a checkpoint.
  return exists_nofollow(dir / kCheckpointFile);
}

fs::path CheckpointStore::archive_log(std::uint64_t generation) const {
  char name[40];
  std::snprintf(name, sizeof(name), "archive-state-%05llu.bin", static_cast<unsigned long long>(generation));
  return dir_ / name;
}

void CheckpointStore::save(const CheckpointCounters& counters, const std::string& config,
                           const std::vector<LogSize>& logs, Archive& archive, const Dataset& dataset,
                           const Components& components) {
  wait();
  Job job;
  // The archive: the slots written since the last checkpoint, or a new generation with every
  // elite when the log would otherwise be more than half stale.
  archive.take_dirty(dirty_);
  const std::size_t rec = record_bytes(param_count_, dims_);
  const std::uint64_t live = kArchiveHeaderBytes + archive.size() * rec;
  Append arch;
  const std::uint64_t saved = archive_chunks_.empty() ? 0 : archive_chunks_.back().end;
  if (saved == 0 || saved + dirty_.size() * rec > 2 * live) {
    if (saved != 0) {
      job.remove_after.push_back(archive_log(archive_generation_));
      ++archive_generation_;
    }
    archive_chunks_.clear();
    arch.offset = 0;
    arch.bytes.reserve(live);
    arch.bytes.append(kArchiveLogMagic, sizeof(kArchiveLogMagic));
    append_raw(arch.bytes, static_cast<std::uint64_t>(param_count_));
    append_raw(arch.bytes, static_cast<std::uint64_t>(dims_));
    dirty_.resize(archive.size());
    std::iota(dirty_.begin(), dirty_.end(), std::size_t{0});
  } else {
    arch.offset = saved;
  }
  arch.path = archive_log(archive_generation_);
  arch.bytes.reserve(arch.bytes.size() + dirty_.size() * rec);
  for (std::size_t slot : dirty_) append_record(arch.bytes, archive, slot);
  archive_chunks_.push_back({arch.offset + arch.bytes.size(), crc32c(arch.bytes.data(), arch.bytes.size())});
  job.appends.push_back(std::move(arch));

  // The dataset: the rows added since the last checkpoint.
  Append data;
  data.path = dir_ / kDatasetFile;
  data.offset = dataset_chunks_.empty() ? 0 : dataset_chunks_.back().end;
  if (data.offset == 0) {
    data.bytes.append(kDatasetMagic, sizeof(kDatasetMagic));
    append_raw(data.bytes, static_cast<std::uint64_t>(param_count_));
  }
  for (std::size_t k = dataset_rows_; k < dataset.size(); ++k) {
    append_raw(data.bytes, dataset.cells()[k]);
    append_raw(data.bytes, static_cast<std::int64_t>(dataset.loops()[k]));
    data.bytes.append(reinterpret_cast<const char*>(dataset.params().row(static_cast<Eigen::Index>(k)).data()),
                      param_count_ * sizeof(double));
  }
  dataset_rows_ = dataset.size();
  dataset_chunks_.push_back({data.offset + data.bytes.size(), crc32c(data.bytes.data(), data.bytes.size())});
  job.appends.push_back(std::move(data));

  std::ostringstream o(std::ios::binary);
  o.write(kCheckpointMagic, sizeof(kCheckpointMagic));
  state::write_string(o, config);
  state::write<std::int32_t>(o, counters.loop);
  state::write<std::uint64_t>(o, counters.evaluations);
  state::write<double>(o, counters.wall_seconds);
  state::write<double>(o, counters.train_seconds);
  state::write<std::uint32_t>(o, static_cast<std::uint32_t>(logs.size()));
  for (const LogSize& log : logs) {
    state::write_string(o, log.name);
    state::write<std::uint64_t>(o, log.size);
    state::write<std::uint32_t>(o, log.crc);
  }
  state::write<std::uint64_t>(o, archive_generation_);
  state::write<std::uint64_t>(o, archive.size());
  state::write<std::uint64_t>(o, dataset.size());
  for (const auto* chunks : {&archive_chunks_, &dataset_chunks_}) {
    state::write<std::uint64_t>(o, chunks->size());
    for (const Chunk& c : *chunks) {
      state::write<std::uint64_t>(o, c.end);
      state::write<std::uint32_t>(o, c.crc);
    }
  }
  state::write_string(o, blob_of(*components.representation));
  state::write_string(o, blob_of(*components.mutator));
  state::write_string(o, blob_of(*components.initial));
  const std::string worlds = components.environment ? blob_of(*components.environment) : std::string();
  state::write_string(o, worlds);
  if (!o) throw SystemError("cannot serialise the checkpoint");
  if (components.environment) {
    std::istringstream back(worlds, std::ios::binary);
    components.environment->load(back);
  }
  job.checkpoint = o.str();
  append_raw(job.checkpoint, crc32c(job.checkpoint.data(), job.checkpoint.size()));

  std::lock_guard<std::mutex> lock(mutex_);
  job_ = std::move(job);
  pending_ = true;
  wake_.notify_one();
}

void CheckpointStore::wait() {
  std::unique_lock<std::mutex> lock(mutex_);
  idle_.wait(lock, [&] { return !pending_; });
  if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
}

void CheckpointStore::work() {
  ::pthread_setname_np(::pthread_self(), "qd-checkpoint");
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    wake_.wait(lock, [&] { return stop_ || pending_; });
    if (!pending_) return;
    lock.unlock();
    std::exception_ptr error;
    try {
      write(job_);
    } catch (...) {
      error = std::current_exception();
    }
    lock.lock();
    job_ = Job();
    error_ = error;
    pending_ = false;
    idle_.notify_all();
  }
}

void CheckpointStore::write(const Job& job) const {
  // Appended data first: a checkpoint that counts it must never be visible before it is durable.
  for (const Append& a : job.appends) {
    // Never through a symlink, and never into an inode a hard-linked copy of the run shares.
    Fd f{open_for_update(a.path, 0, true)};
    if (::ftruncate(f.fd, static_cast<off_t>(a.offset)) != 0 ||
        ::lseek(f.fd, static_cast<off_t>(a.offset), SEEK_SET) < 0)
      throw SystemError("cannot truncate " + a.path.string() + ": " + std::strerror(errno));
    write_all(f.fd, a.bytes.data(), a.bytes.size(), a.path);
    if (::fsync(f.fd) != 0) throw SystemError("cannot flush " + a.path.string() + ": " + std::strerror(errno));
  }
  write_file_atomic(dir_ / kCheckpointFile, job.checkpoint);
  for (const auto& p : job.remove_after) {
    std::error_code ec;
    fs::remove(p, ec);  // only space is lost if this fails
  }
}

namespace {
// Reads an append-only file and checks every chunk against its recorded CRC-32C.
std::string read_verified(const fs::path& path, const std::vector<CheckpointStore::Chunk>& chunks) {
  const std::uint64_t size = chunks.empty() ? 0 : chunks.back().end;
  // Only a regular file, and only the bytes the checkpoint vouches for.
  const std::string bytes = read_run_file_prefix(path, size);
  std::uint64_t begin = 0;
  for (const auto& c : chunks) {
    if (c.end < begin || c.end > size)
      throw StateError("the checkpoint's chunk list of " + path.string() + " is inconsistent");
    if (crc32c(bytes.data() + begin, c.end - begin) != c.crc)
      throw StateError(path.string() + ": bytes " + std::to_string(begin) + " to " + std::to_string(c.end) +
                       " do not match their checksum (the file was changed or corrupted)");
    begin = c.end;
  }
  return bytes;
}
}  // namespace

void CheckpointStore::load_archive(Archive& archive, std::uint64_t slots, bool tidy) {
  const fs::path path = archive_log(archive_generation_);
  const std::string bytes = read_verified(path, archive_chunks_);
  std::uint64_t shape[2] = {0, 0};
  if (bytes.size() < kArchiveHeaderBytes || !std::equal(kArchiveLogMagic, kArchiveLogMagic + 8, bytes.data()))
    throw StateError(path.string() + " is not a qdrun archive state file");
  std::memcpy(shape, bytes.data() + 8, sizeof(shape));
  if (shape[0] != param_count_ || shape[1] != dims_)
    throw StateError(path.string() + " has another shape than this experiment");
  const std::size_t rec = record_bytes(param_count_, dims_);
  if ((bytes.size() - kArchiveHeaderBytes) % rec != 0)
    throw StateError("the checkpoint's archive size is inconsistent");
  std::vector<double> desc(dims_), theta(param_count_);
  for (std::size_t at = kArchiveHeaderBytes; at < bytes.size(); at += rec) {
    const char* r = bytes.data() + at;
    std::int64_t head[2];
    double values[2];
    std::memcpy(head, r, sizeof(head));
    std::memcpy(values, r + 16, sizeof(values));
    std::memcpy(desc.data(), r + 32, dims_ * sizeof(double));
    std::memcpy(theta.data(), r + 32 + dims_ * sizeof(double), param_count_ * sizeof(double));
    if (head[0] < 0) throw StateError(path.string() + " holds a negative slot at byte " + std::to_string(at));
    archive.restore(static_cast<std::size_t>(head[0]), head[1], theta.data(), desc.data(), values[0], values[1]);
  }
  if (archive.size() != slots) throw StateError(path.string() + " does not hold the checkpoint's elites");
  if (tidy) {  // generations of a compaction whose checkpoint never committed
    for (const auto& e : fs::directory_iterator(dir_)) {
      const std::string name = e.path().filename().string();
      if (name.rfind("archive-state-", 0) == 0 && e.path() != path) fs::remove(e.path());
    }
  }
}

void CheckpointStore::load_dataset(Dataset& dataset, std::uint64_t rows) {
  const fs::path path = dir_ / kDatasetFile;
  const std::string bytes = read_verified(path, dataset_chunks_);
  std::uint64_t P = 0;
  if (bytes.size() < kDatasetHeaderBytes || !std::equal(kDatasetMagic, kDatasetMagic + 8, bytes.data()))
    throw StateError(path.string() + " is not a qdrun dataset file");
  std::memcpy(&P, bytes.data() + 8, sizeof(P));
  if (P != param_count_) throw StateError(path.string() + " has another parameter count than this experiment");
  const std::size_t row = dataset_row_bytes(param_count_);
  if (bytes.size() != kDatasetHeaderBytes + rows * row)
    throw StateError(path.string() + " does not hold the checkpoint's " + std::to_string(rows) + " rows");
  std::vector<double> theta(param_count_);
  for (std::size_t at = kDatasetHeaderBytes; at < bytes.size(); at += row) {
    std::int64_t cell = 0, loop = 0;
    std::memcpy(&cell, bytes.data() + at, 8);
    std::memcpy(&loop, bytes.data() + at + 8, 8);
    std::memcpy(theta.data(), bytes.data() + at + 16, param_count_ * sizeof(double));
    if (cell < 0 || dataset.contains_cell(cell))
      throw StateError(path.string() + " holds an invalid or repeated cell at byte " + std::to_string(at));
    dataset.add(theta.data(), cell, static_cast<int>(loop));
  }
  dataset_rows_ = dataset.size();
}

CheckpointStore::Loaded CheckpointStore::load(Archive& archive, Dataset& dataset, const Components& components,
                                              bool tidy) {
  const fs::path file = dir_ / kCheckpointFile;
  std::string bytes = read_run_file(file, kMaxCheckpointBytes);
  std::uint32_t stored_crc = 0;
  const bool v03 = bytes.size() >= sizeof(kCheckpointMagic03) &&
                   std::equal(kCheckpointMagic03, kCheckpointMagic03 + sizeof(kCheckpointMagic03), bytes.data());
  if (bytes.size() < sizeof(kCheckpointMagic) + sizeof(stored_crc) ||
      (!v03 && !std::equal(kCheckpointMagic, kCheckpointMagic + sizeof(kCheckpointMagic), bytes.data())))
    throw StateError(file.string() + " is not a qdrun checkpoint of this version");
  std::memcpy(&stored_crc, bytes.data() + bytes.size() - sizeof(stored_crc), sizeof(stored_crc));
  bytes.resize(bytes.size() - sizeof(stored_crc));
  if (crc32c(bytes.data(), bytes.size()) != stored_crc)
    throw StateError(file.string() + " does not match its checksum (the file was changed or corrupted)");
  std::istringstream i(bytes, std::ios::binary);
  i.ignore(sizeof(kCheckpointMagic));
  Loaded out;
  out.config = state::read_string(i);
  out.counters.loop = state::read<std::int32_t>(i);
  out.counters.evaluations = state::read<std::uint64_t>(i);
  out.counters.wall_seconds = state::read<double>(i);
  out.counters.train_seconds = state::read<double>(i);
  const auto nlogs = state::read<std::uint32_t>(i);
  for (std::uint32_t k = 0; k < nlogs; ++k) {
    LogSize log;
    log.name = state::read_string(i);
    log.size = state::read<std::uint64_t>(i);
    log.crc = v03 ? 0 : state::read<std::uint32_t>(i);
    log.checksummed = !v03;
    // A recorded name is a plain file name of the run directory, never a path out of it.
    if (log.name.empty() || log.name.find('/') != std::string::npos || log.name == "." || log.name == "..")
      throw StateError(file.string() + " records a log named '" + log.name + "'");
    out.logs.push_back(std::move(log));
  }
  archive_generation_ = state::read<std::uint64_t>(i);
  const auto archive_slots = state::read<std::uint64_t>(i);
  const auto dataset_rows = state::read<std::uint64_t>(i);
  for (auto* chunks : {&archive_chunks_, &dataset_chunks_}) {
    // Each chunk takes 12 bytes of the file: a count beyond what is left is damage, not a size to
    // allocate.
    const auto count = state::read<std::uint64_t>(i);
    if (count > bytes.size() / 12) throw StateError(file.string() + " records an impossible number of chunks");
    chunks->resize(count);
    for (Chunk& c : *chunks) {
      c.end = state::read<std::uint64_t>(i);
      c.crc = state::read<std::uint32_t>(i);
    }
  }
  load_archive(archive, archive_slots, tidy);
  load_dataset(dataset, dataset_rows);
  auto blob = [&](auto& component, const char* what) {
    std::istringstream b(state::read_string(i), std::ios::binary);
    try {
      component.load(b);
    } catch (const std::exception& e) {
      throw StateError(file.string() + ": " + what + " state: " + e.what());
    }
  };
  blob(*components.representation, "representation");
  blob(*components.mutator, "mutator");
  blob(*components.initial, "initial sampler");
  // Checkpoints of earlier versions end here: they hold no environment state.
  std::string worlds;
  if (i.peek() != std::char_traits<char>::eof()) worlds = state::read_string(i);
  if (components.environment) {
    if (worlds.empty())
      throw StateError(file.string() +
                       ": holds no state of the environment's persistent worlds (made by a qdrun "
                       "without them, or with another environment setting)");
    std::istringstream b(worlds, std::ios::binary);
    try {
      components.environment->load(b);
    } catch (const std::exception& e) {
      throw StateError(file.string() + ": environment state: " + e.what());
    }
  }
  return out;
}

}  // namespace qd::runtime
