#include "runtime/checkpoint_writer.hpp"

#include "runtime/csv.hpp"

#include <qd/errors.hpp>

#include <fcntl.h>
#include <unistd.h>
#include <cerrno>
#include <cstring>
#include <utility>

namespace qd::runtime {
namespace {

void write_at(int fd, const std::string& bytes, std::uint64_t offset, const std::filesystem::path& path) {
  const char* p = bytes.data();
  std::size_t left = bytes.size();
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

}  // namespace

CheckpointWriter::CheckpointWriter() : thread_([this] { work(); }) {}

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

void CheckpointWriter::work() {
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

void CheckpointWriter::write(const Job& job) {
  // Dataset rows first: the checkpoint that counts them must never be visible before they are durable.
  {
    Fd f{::open(job.dataset.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644)};
    if (f.fd < 0) throw Error("cannot open " + job.dataset.string() + ": " + std::strerror(errno));
    // Rows past the committed size come from a checkpoint that never committed.
    if (::ftruncate(f.fd, static_cast<off_t>(job.dataset_offset)) != 0)
      throw Error("cannot truncate " + job.dataset.string() + ": " + std::strerror(errno));
    write_at(f.fd, job.dataset_rows, job.dataset_offset, job.dataset);
    if (::fsync(f.fd) != 0) throw Error("cannot flush " + job.dataset.string() + ": " + std::strerror(errno));
  }
  const std::filesystem::path tmp = job.checkpoint.string() + ".tmp";
  {
    Fd f{::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644)};
    if (f.fd < 0) throw Error("cannot create " + tmp.string() + ": " + std::strerror(errno));
    write_at(f.fd, job.state, 0, tmp);
  }
  commit_file(tmp, job.checkpoint);
}

}  // namespace qd::runtime
