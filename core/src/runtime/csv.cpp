#include "runtime/csv.hpp"
#include "runtime/number_format.hpp"

#include <qd/errors.hpp>

#include <fcntl.h>
#if defined(__AVX__)
#include <immintrin.h>
#endif
#include <unistd.h>
#include <algorithm>
#include <cerrno>
#include <charconv>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <exception>
#include <memory>
#include <mutex>
#include <system_error>
#include <thread>
#include <utility>
#include <vector>

namespace qd::runtime {
namespace fs = std::filesystem;

void append_number(std::string& out, double v) {
  clear_upper_vector_state();  // about 1 cycle; the rare to_chars fallback is built for generic x86-64
  char buf[kNumberBufferBytes];
  out.append(buf, write_number(v, buf));
}

void clear_upper_vector_state() noexcept {
#if defined(__AVX__)
  _mm256_zeroupper();  // the compiler knows what it clobbers
#elif defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
  // Built without AVX, this code keeps nothing in the upper halves; vzeroupper keeps the rest.
  static const bool has_avx = __builtin_cpu_supports("avx");
  if (has_avx) __asm__ volatile("vzeroupper");
#endif
}

std::string format_number(double v) {
  std::string s;
  append_number(s, v);
  return s;
}

void append_int(std::string& out, std::int64_t v) {
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof(buf), v);
  out.append(buf, r.ptr);
}

namespace {
void write_all(int fd, const char* p, std::size_t left, const fs::path& path) {
  while (left > 0) {
    const ssize_t w = ::write(fd, p, left);
    if (w < 0) {
      if (errno == EINTR) continue;
      throw Error("cannot write " + path.string() + ": " + std::strerror(errno));
    }
    p += w;
    left -= static_cast<std::size_t>(w);
  }
}

// Moves a flushed temporary file over `path`, then flushes the directory so the rename survives
// a crash.
void rename_durably(const fs::path& tmp, const fs::path& path) {
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) throw Error("cannot rename " + tmp.string() + " to " + path.string() + ": " + ec.message());
  const int dfd =
      ::open(path.parent_path().empty() ? "." : path.parent_path().c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
}
}  // namespace

void format_in_order(std::size_t blocks, std::size_t max_block_bytes, unsigned threads,
                     const std::function<char*(std::size_t block, char* out)>& format,
                     const std::function<void(const char* text, std::size_t size)>& write) {
  if (blocks == 0) return;
  threads = static_cast<unsigned>(std::clamp<std::size_t>(threads, 1, blocks));
  // Piece b is formatted into ring[b % window]; it may be claimed once piece b - window is
  // written, so a slot has one user at a time and needs no lock while it is formatted.
  struct Slot {
    std::unique_ptr<char[]> bytes;
    std::size_t size = 0;
    bool done = false;
  };
  const std::size_t window = 2 * static_cast<std::size_t>(threads);
  std::vector<Slot> ring(window);
  std::mutex mutex;
  std::condition_variable changed;
  std::size_t next = 0, written = 0;
  std::exception_ptr error;
  auto work = [&](bool writer) {
    std::unique_lock<std::mutex> lock(mutex);
    auto fail = [&] {
      lock.lock();
      if (!error) error = std::current_exception();
      changed.notify_all();
    };
    while (!error) {
      Slot& oldest = ring[written % window];
      if (writer && written < blocks && oldest.done) {
        lock.unlock();
        try {
          write(oldest.bytes.get(), oldest.size);
        } catch (...) {
          fail();
          return;
        }
        lock.lock();
        oldest.done = false;
        ++written;
        changed.notify_all();
        continue;
      }
      if (writer && written == blocks) return;
      if (next < blocks && next < written + window) {
        const std::size_t b = next++;
        Slot& slot = ring[b % window];
        lock.unlock();
        try {
          if (!slot.bytes) slot.bytes.reset(new char[max_block_bytes]);  // uninitialised: no memset
          const char* end = format(b, slot.bytes.get());
          QD_CHECK(end >= slot.bytes.get() && static_cast<std::size_t>(end - slot.bytes.get()) <= max_block_bytes,
                   "format_in_order: a piece overran its buffer");
          slot.size = static_cast<std::size_t>(end - slot.bytes.get());
        } catch (...) {
          fail();
          return;
        }
        lock.lock();
        slot.done = true;
        changed.notify_all();
        continue;
      }
      if (!writer && next == blocks) return;
      changed.wait(lock);
    }
  };
  std::vector<std::thread> helpers;
  for (unsigned i = 1; i < threads; ++i) {
    try {
      helpers.emplace_back(work, false);
    } catch (const std::system_error&) {
      break;  // fewer threads: slower, still complete
    }
  }
  work(true);
  for (auto& t : helpers) t.join();
  if (error) std::rethrow_exception(error);
}

void write_file_atomic(const fs::path& path, const std::string& content) {
  AtomicFile file(path);
  file.write(content);
  file.commit();
}

AtomicFile::AtomicFile(fs::path path) : path_(std::move(path)), tmp_(path_.string() + ".tmp") {
  fd_ = ::open(tmp_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0) throw Error("cannot create " + tmp_.string() + ": " + std::strerror(errno));
}

AtomicFile::~AtomicFile() {
  if (fd_ < 0) return;
  ::close(fd_);
  ::unlink(tmp_.c_str());
}

void AtomicFile::write(const char* bytes, std::size_t size) {
  write_all(fd_, bytes, size, tmp_);
#ifdef __linux__
  // Start writing this piece back now, asynchronously (errors surface at the fsync).
  ::sync_file_range(fd_, static_cast<off_t>(written_), static_cast<off_t>(size), SYNC_FILE_RANGE_WRITE);
#endif
  written_ += size;
}

void AtomicFile::commit() {
  if (::fsync(fd_) != 0) throw Error("cannot flush " + tmp_.string() + ": " + std::strerror(errno));
  if (::close(fd_) != 0) {
    fd_ = -1;
    throw Error("cannot write " + tmp_.string() + ": " + std::strerror(errno));
  }
  fd_ = -1;
  rename_durably(tmp_, path_);
}

void commit_file(const fs::path& tmp, const fs::path& path) {
  const int fd = ::open(tmp.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0 || ::fsync(fd) != 0) throw Error("cannot flush " + tmp.string());
  ::close(fd);
  rename_durably(tmp, path);
}

AppendLog::~AppendLog() {
  try {
    flush();
  } catch (const Error&) {
  }
  if (fd_ >= 0) ::close(fd_);
}

void AppendLog::append(const fs::path& path, const std::string& text) {
  if (fd_ < 0) {
    fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    if (fd_ < 0) throw Error("cannot open " + path.string() + " for appending: " + std::strerror(errno));
    path_ = path;
    last_flush_ = std::chrono::steady_clock::now();
  }
  QD_CHECK(path.native() == path_.native(), "one AppendLog appends to one file");  // not path's per-component compare
  pending_ += text;
  if (std::chrono::steady_clock::now() - last_flush_ >= flush_interval_) flush();
}

void AppendLog::flush() {
  if (fd_ < 0 || pending_.empty()) return;
  last_flush_ = std::chrono::steady_clock::now();
  std::string text;
  text.swap(pending_);
  write_all(fd_, text.data(), text.size(), path_);
  text.clear();
  pending_.swap(text);  // keeps the capacity
}

void append_to_file(const fs::path& path, const std::string& text) {
  AppendLog log(std::chrono::seconds(0));
  log.append(path, text);
}

}  // namespace qd::runtime
