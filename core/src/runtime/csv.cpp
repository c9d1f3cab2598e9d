#include "runtime/csv.hpp"

#include <qd/errors.hpp>

#include <fcntl.h>
#include <unistd.h>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <system_error>

namespace qd::runtime {
namespace fs = std::filesystem;

void append_number(std::string& out, double v) {
  if (std::isnan(v)) {
    out += "nan";
    return;
  }
  char buf[32];
  out.append(buf, std::to_chars(buf, buf + sizeof(buf), v).ptr);
}

std::string format_number(double v) {
  std::string s;
  append_number(s, v);
  return s;
}

void append_int(std::string& out, std::int64_t v) {
  char buf[24];
  out.append(buf, std::to_chars(buf, buf + sizeof(buf), v).ptr);
}

void write_all(int fd, const char* bytes, std::size_t size, const fs::path& path) {
  while (size > 0) {
    const ssize_t w = ::write(fd, bytes, size);
    if (w < 0) {
      if (errno == EINTR) continue;
      throw SystemError("cannot write " + path.string() + ": " + std::strerror(errno));
    }
    bytes += w;
    size -= static_cast<std::size_t>(w);
  }
}

namespace {
// Moves a flushed temporary file over `path`, then flushes the directory so the rename survives
// a crash.
void rename_durably(const fs::path& tmp, const fs::path& path) {
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) throw SystemError("cannot rename " + tmp.string() + " to " + path.string() + ": " + ec.message());
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
  if (fd_ < 0) throw SystemError("cannot create " + tmp_.string() + ": " + std::strerror(errno));
}

AtomicFile::~AtomicFile() {
  if (fd_ < 0) return;
  ::close(fd_);
  ::unlink(tmp_.c_str());
}

void AtomicFile::commit() {
  if (::fsync(fd_) != 0) throw SystemError("cannot flush " + tmp_.string() + ": " + std::strerror(errno));
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) {
    ::unlink(tmp_.c_str());
    throw SystemError("cannot write " + tmp_.string() + ": " + std::strerror(errno));
  }
  rename_durably(tmp_, path_);
}

AppendLog::~AppendLog() {
  if (fd_ >= 0) ::close(fd_);
}

void AppendLog::append(const std::string& text) {
  if (fd_ < 0) {
    fd_ = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    if (fd_ < 0) throw SystemError("cannot open " + path_.string() + " for appending: " + std::strerror(errno));
  }
  write_all(fd_, text.data(), text.size(), path_);
}

void append_to_file(const fs::path& path, const std::string& text) {
  AppendLog log(path);
  log.append(text);
}

}  // namespace qd::runtime
