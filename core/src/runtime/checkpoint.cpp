#include "runtime/checkpoint.hpp"

#include "runtime/csv.hpp"

#include <qd/errors.hpp>
#include <qd/state_io.hpp>

#include <fcntl.h>
#include <pthread.h>
#include <unistd.h>
#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <numeric>
#include <sstream>

namespace qd::runtime {
namespace fs = std::filesystem;

namespace {
constexpr char kCheckpointMagic[8] = {'Q', 'D', 'C', 'K', 'P', 'T', '0', '2'};
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
    : dir_(std::move(dir)), param_count_(param_count), dims_(descriptor_dims), thread_([this] { work(); }) {}

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
  std::error_code ec;
  return fs::exists(dir / kCheckpointFile, ec);
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
  if (archive_bytes_ == 0 || archive_bytes_ + dirty_.size() * rec > 2 * live) {
    if (archive_bytes_ != 0) {
      job.remove_after.push_back(archive_log(archive_generation_));
      ++archive_generation_;
    }
    arch.offset = 0;
    arch.bytes.reserve(live);
    arch.bytes.append(kArchiveLogMagic, sizeof(kArchiveLogMagic));
    append_raw(arch.bytes, static_cast<std::uint64_t>(param_count_));
    append_raw(arch.bytes, static_cast<std::uint64_t>(dims_));
    dirty_.resize(archive.size());
    std::iota(dirty_.begin(), dirty_.end(), std::size_t{0});
  } else {
    arch.offset = archive_bytes_;
  }
  arch.path = archive_log(archive_generation_);
  arch.bytes.reserve(arch.bytes.size() + dirty_.size() * rec);
  for (std::size_t slot : dirty_) append_record(arch.bytes, archive, slot);
  archive_bytes_ = arch.offset + arch.bytes.size();
  job.appends.push_back(std::move(arch));

  // The dataset: the rows added since the last checkpoint.
  Append data;
  data.path = dir_ / kDatasetFile;
  data.offset = dataset_bytes_;
  if (dataset_bytes_ == 0) {
    data.bytes.append(kDatasetMagic, sizeof(kDatasetMagic));
    append_raw(data.bytes, static_cast<std::uint64_t>(param_count_));
  }
  for (std::size_t k = dataset_rows_; k < dataset.size(); ++k) {
    append_raw(data.bytes, dataset.cells()[k]);
    append_raw(data.bytes, static_cast<std::int64_t>(dataset.loops()[k]));
    data.bytes.append(reinterpret_cast<const char*>(dataset.params().row(static_cast<Eigen::Index>(k)).data()),
                      param_count_ * sizeof(double));
  }
  dataset_bytes_ = data.offset + data.bytes.size();
  dataset_rows_ = dataset.size();
  job.appends.push_back(std::move(data));

  std::ostringstream o(std::ios::binary);
  o.write(kCheckpointMagic, sizeof(kCheckpointMagic));
  state::write_string(o, config);
  state::write<std::int32_t>(o, counters.loop);
  state::write<std::uint64_t>(o, counters.evaluations);
  state::write<double>(o, counters.wall_seconds);
  state::write<double>(o, counters.train_seconds);
  state::write<std::uint32_t>(o, static_cast<std::uint32_t>(logs.size()));
  for (const auto& [name, size] : logs) {
    state::write_string(o, name);
    state::write<std::uint64_t>(o, size);
  }
  state::write<std::uint64_t>(o, archive_generation_);
  state::write<std::uint64_t>(o, archive_bytes_);
  state::write<std::uint64_t>(o, archive.size());
  state::write<std::uint64_t>(o, dataset.size());
  state::write_string(o, blob_of(*components.representation));
  state::write_string(o, blob_of(*components.mutator));
  state::write_string(o, blob_of(*components.initial));
  if (!o) throw Error("cannot serialise the checkpoint");
  job.checkpoint = o.str();

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
    Fd f{::open(a.path.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644)};
    if (f.fd < 0) throw Error("cannot open " + a.path.string() + ": " + std::strerror(errno));
    if (::ftruncate(f.fd, static_cast<off_t>(a.offset)) != 0 ||
        ::lseek(f.fd, static_cast<off_t>(a.offset), SEEK_SET) < 0)
      throw Error("cannot truncate " + a.path.string() + ": " + std::strerror(errno));
    write_all(f.fd, a.bytes.data(), a.bytes.size(), a.path);
    if (::fsync(f.fd) != 0) throw Error("cannot flush " + a.path.string() + ": " + std::strerror(errno));
  }
  write_file_atomic(dir_ / kCheckpointFile, job.checkpoint);
  for (const auto& p : job.remove_after) {
    std::error_code ec;
    fs::remove(p, ec);  // only space is lost if this fails
  }
}

void CheckpointStore::load_archive(Archive& archive, std::uint64_t generation, std::uint64_t bytes, std::uint64_t slots,
                                   bool tidy) {
  const fs::path path = archive_log(generation);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw StateError(path.string() + " is missing");
  char magic[sizeof(kArchiveLogMagic)];
  std::uint64_t P = 0, dims = 0;
  if (!in.read(magic, sizeof(magic)) || !std::equal(magic, magic + sizeof(magic), kArchiveLogMagic) ||
      !in.read(reinterpret_cast<char*>(&P), sizeof(P)) || !in.read(reinterpret_cast<char*>(&dims), sizeof(dims)))
    throw StateError(path.string() + " is not a qdrun archive state file");
  if (P != param_count_ || dims != dims_) throw StateError(path.string() + " has another shape than this experiment");
  const std::size_t rec = record_bytes(param_count_, dims_);
  if (bytes < kArchiveHeaderBytes || (bytes - kArchiveHeaderBytes) % rec != 0)
    throw StateError("the checkpoint's archive size is inconsistent");
  std::vector<char> buf(rec);
  for (std::uint64_t k = 0, n = (bytes - kArchiveHeaderBytes) / rec; k < n; ++k) {
    if (!in.read(buf.data(), static_cast<std::streamsize>(rec)))
      throw StateError(path.string() + " is shorter than the checkpoint counts");
    std::int64_t head[2];
    double values[2];
    std::memcpy(head, buf.data(), sizeof(head));
    std::memcpy(values, buf.data() + 16, sizeof(values));
    std::vector<double> desc(dims_), theta(param_count_);
    std::memcpy(desc.data(), buf.data() + 32, dims_ * sizeof(double));
    std::memcpy(theta.data(), buf.data() + 32 + dims_ * sizeof(double), param_count_ * sizeof(double));
    if (head[0] < 0) throw StateError(path.string() + " holds a negative slot");
    archive.restore(static_cast<std::size_t>(head[0]), head[1], theta.data(), desc.data(), values[0], values[1]);
  }
  if (archive.size() != slots) throw StateError(path.string() + " does not hold the checkpoint's elites");
  archive_generation_ = generation;
  archive_bytes_ = bytes;
  if (tidy) {  // generations of a compaction whose checkpoint never committed
    for (const auto& e : fs::directory_iterator(dir_)) {
      const std::string name = e.path().filename().string();
      if (name.rfind("archive-state-", 0) == 0 && e.path() != path) fs::remove(e.path());
    }
  }
}

void CheckpointStore::load_dataset(Dataset& dataset, std::uint64_t rows) {
  const fs::path path = dir_ / kDatasetFile;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw StateError(path.string() + " is missing");
  char magic[sizeof(kDatasetMagic)];
  std::uint64_t P = 0;
  if (!in.read(magic, sizeof(magic)) || !std::equal(magic, magic + sizeof(magic), kDatasetMagic) ||
      !in.read(reinterpret_cast<char*>(&P), sizeof(P)))
    throw StateError(path.string() + " is not a qdrun dataset file");
  if (P != param_count_) throw StateError(path.string() + " has another parameter count than this experiment");
  std::vector<double> theta(P);
  for (std::uint64_t k = 0; k < rows; ++k) {
    std::int64_t cell = 0, loop = 0;
    if (!in.read(reinterpret_cast<char*>(&cell), sizeof(cell)) ||
        !in.read(reinterpret_cast<char*>(&loop), sizeof(loop)) ||
        !in.read(reinterpret_cast<char*>(theta.data()), static_cast<std::streamsize>(P * sizeof(double))))
      throw StateError(path.string() + " holds fewer rows than the checkpoint counts");
    if (dataset.contains_cell(cell)) throw StateError(path.string() + " holds a cell twice");
    dataset.add(theta.data(), cell, static_cast<int>(loop));
  }
  dataset_rows_ = dataset.size();
  dataset_bytes_ = kDatasetHeaderBytes + rows * dataset_row_bytes(P);
}

CheckpointStore::Loaded CheckpointStore::load(Archive& archive, Dataset& dataset, const Components& components,
                                              bool tidy) {
  const fs::path file = dir_ / kCheckpointFile;
  std::ifstream in(file, std::ios::binary);
  if (!in) throw StateError(file.string() + " is missing");
  std::stringstream ss;
  ss << in.rdbuf();
  std::istringstream i(ss.str(), std::ios::binary);
  char magic[sizeof(kCheckpointMagic)];
  if (!i.read(magic, sizeof(magic)) || !std::equal(magic, magic + sizeof(magic), kCheckpointMagic))
    throw StateError(file.string() + " is not a qdrun checkpoint");
  Loaded out;
  out.config = state::read_string(i);
  out.counters.loop = state::read<std::int32_t>(i);
  out.counters.evaluations = state::read<std::uint64_t>(i);
  out.counters.wall_seconds = state::read<double>(i);
  out.counters.train_seconds = state::read<double>(i);
  const auto nlogs = state::read<std::uint32_t>(i);
  for (std::uint32_t k = 0; k < nlogs; ++k) {
    std::string name = state::read_string(i);
    out.logs.emplace_back(std::move(name), state::read<std::uint64_t>(i));
  }
  const auto generation = state::read<std::uint64_t>(i);
  const auto archive_bytes = state::read<std::uint64_t>(i);
  const auto archive_slots = state::read<std::uint64_t>(i);
  const auto dataset_rows = state::read<std::uint64_t>(i);
  load_archive(archive, generation, archive_bytes, archive_slots, tidy);
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
  return out;
}

}  // namespace qd::runtime
