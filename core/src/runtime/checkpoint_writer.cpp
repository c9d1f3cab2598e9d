#include "runtime/checkpoint_writer.hpp"

#include "runtime/csv.hpp"

#include <qd/errors.hpp>

#include <fcntl.h>
#include <pthread.h>
#include <unistd.h>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <utility>

namespace qd::runtime {
namespace {

void write_at(int fd, const char* p, std::size_t left, std::uint64_t offset, const std::filesystem::path& path) {
  auto at = static_cast<off_t>(offset);
  while (left > 0) {
    const ssize_t w = ::pwrite(fd, p, left, at);
    if (w < 0) {
      if (errno == EINTR) continue;
      throw Error("cannot write " + path.string() + ": " + std::strerror(errno));
    }
    p += w;
    at += w;
    left -= static_cast<std::size_t>(w);
  }
}

struct Fd {
  int fd;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

// Writes a new file with O_DIRECT (see Append::direct), durably. Returns false, having written
// nothing that counts, when the file system does not take O_DIRECT (EINVAL); throws on other errors.
bool write_direct(const CheckpointWriter::Append& a) {
  Fd f{::open(a.path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC | O_DIRECT, 0644)};
  if (f.fd < 0) {
    if (errno == EINVAL) return false;
    throw Error("cannot open " + a.path.string() + ": " + std::strerror(errno));
  }
  const std::size_t align = CheckpointWriter::kDirectAlignment;
  const std::size_t padded = (a.more_size + align - 1) / align * align;
  std::size_t done = 0;
  while (done < padded) {
    const ssize_t w = ::pwrite(f.fd, a.more + done, padded - done, static_cast<off_t>(done));
    if (w < 0 && errno == EINTR) continue;
    if (w < 0 && errno == EINVAL && done == 0) return false;
    if (w < 0) throw Error("cannot write " + a.path.string() + ": " + std::strerror(errno));
    if (w == 0 || static_cast<std::size_t>(w) % align != 0) return false;  // cannot go on aligned
    done += static_cast<std::size_t>(w);
  }
  if (::ftruncate(f.fd, static_cast<off_t>(a.more_size)) != 0)  // the padding goes
    throw Error("cannot truncate " + a.path.string() + ": " + std::strerror(errno));
  if (::fsync(f.fd) != 0) throw Error("cannot flush " + a.path.string() + ": " + std::strerror(errno));
  return true;
}

}  // namespace

CheckpointWriter::CheckpointWriter(bool direct_io) : direct_io_(direct_io), thread_([this] { work(); }) {}

CheckpointWriter::~CheckpointWriter() {
  {
    std::unique_lock<std::mutex> lock(mutex_);
    idle_.wait(lock, [&] { return !pending_; });
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void CheckpointWriter::submit(Job& job) {
  std::unique_lock<std::mutex> lock(mutex_);
  idle_.wait(lock, [&] { return !pending_; });
  if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
  std::swap(job_, job);
  pending_ = true;
  lock.unlock();
  wake_.notify_one();
}

void CheckpointWriter::wait() {
  std::unique_lock<std::mutex> lock(mutex_);
  idle_.wait(lock, [&] { return !pending_; });
  if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
}

bool CheckpointWriter::busy() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return pending_;
}

void CheckpointWriter::work() {
  ::pthread_setname_np(::pthread_self(), "qd-checkpoint");  // named for top -H and the benchmark
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
    error_ = error;
    pending_ = false;
    idle_.notify_all();
  }
}

void CheckpointWriter::write(const Job& job) const {
  if (job.prepare) job.prepare();
  // Appended data first: a checkpoint that counts it must never be visible before it is durable.
  for (const Append& a : job.appends) {
    if (a.direct) {
      QD_CHECK(a.offset == 0 && a.bytes.empty() && reinterpret_cast<std::uintptr_t>(a.more) % kDirectAlignment == 0,
               "a direct append is a whole file from an aligned buffer");
      if (direct_io_ && write_direct(a)) continue;
    }
    Fd f{::open(a.path.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644)};
    if (f.fd < 0) throw Error("cannot open " + a.path.string() + ": " + std::strerror(errno));
    if (::ftruncate(f.fd, static_cast<off_t>(a.offset)) != 0)
      throw Error("cannot truncate " + a.path.string() + ": " + std::strerror(errno));
    write_at(f.fd, a.bytes.data(), a.bytes.size(), a.offset, a.path);
    if (a.more_size > 0) write_at(f.fd, a.more, a.more_size, a.offset + a.bytes.size(), a.path);
    if (::fsync(f.fd) != 0) throw Error("cannot flush " + a.path.string() + ": " + std::strerror(errno));
  }
  const std::filesystem::path tmp = job.checkpoint.string() + ".tmp";
  {
    Fd f{::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644)};
    if (f.fd < 0) throw Error("cannot create " + tmp.string() + ": " + std::strerror(errno));
    write_at(f.fd, job.state.data(), job.state.size(), 0, tmp);
  }
  commit_file(tmp, job.checkpoint);
  for (const auto& p : job.remove_after) {
    std::error_code ec;
    std::filesystem::remove(p, ec);  // only space is lost if this fails
  }
}

}  // namespace qd::runtime
