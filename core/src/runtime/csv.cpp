#include "runtime/csv.hpp"

#include <qd/errors.hpp>

#include <fcntl.h>
#if defined(__AVX__)
#include <immintrin.h>
#endif
#include <unistd.h>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <utility>

namespace qd::runtime {
namespace fs = std::filesystem;

void append_number(std::string& out, double v) {
  if (std::isnan(v)) {
    out += "nan";
    return;
  }
  if (std::isinf(v)) {
    out += v > 0 ? "inf" : "-inf";
    return;
  }
  clear_upper_vector_state();  // about 1 cycle; to_chars is built for generic x86-64 (SSE)
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof(buf), v);
  out.append(buf, r.ptr);
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
void write_all(int fd, const std::string& content, const fs::path& path) {
  const char* p = content.data();
  std::size_t left = content.size();
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

void AtomicFile::write(const std::string& bytes) {
  write_all(fd_, bytes, tmp_);
#ifdef __linux__
  // Start writing this piece back now, asynchronously (errors surface at the fsync).
  ::sync_file_range(fd_, static_cast<off_t>(written_), static_cast<off_t>(bytes.size()), SYNC_FILE_RANGE_WRITE);
#endif
  written_ += bytes.size();
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
  QD_CHECK(path == path_, "one AppendLog appends to one file");
  pending_ += text;
  if (std::chrono::steady_clock::now() - last_flush_ >= flush_interval_) flush();
}

void AppendLog::flush() {
  if (fd_ < 0 || pending_.empty()) return;
  last_flush_ = std::chrono::steady_clock::now();
  std::string text;
  text.swap(pending_);
  write_all(fd_, text, path_);
  text.clear();
  pending_.swap(text);  // keeps the capacity
}

void append_to_file(const fs::path& path, const std::string& text) {
  AppendLog log(std::chrono::seconds(0));
  log.append(path, text);
}

}  // namespace qd::runtime
