#include "runtime/run_files.hpp"

#include <qd/errors.hpp>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <system_error>

namespace qd::runtime {
namespace fs = std::filesystem;

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

// What a file that is not a regular one is, for the messages.
std::string what_it_is(mode_t mode) {
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISSOCK(mode)) return "a socket";
  if (S_ISLNK(mode)) return "a symbolic link";
  return "not a file";
}

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
  require_replaceable(path_);
  // A leftover of an interrupted write, or a symlink someone put there: never written through.
  ::unlink(tmp_.c_str());
  fd_ = ::open(tmp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0644);
  if (fd_ < 0) {
    const int e = errno;
    struct stat st;
    if (e == EEXIST && ::lstat(tmp_.c_str(), &st) == 0)  // what unlink could not remove: a directory
      throw InputError(tmp_.string() + " is " + what_it_is(st.st_mode) +
                       ", where qdrun writes its temporary file for " + path_.filename().string() + "; move it away");
    throw SystemError("cannot create " + tmp_.string() + ": " + std::strerror(e));
  }
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
  try {
    rename_durably(tmp_, path_);
  } catch (...) {
    ::unlink(tmp_.c_str());  // not left behind when the rename fails
    throw;
  }
}

AppendLog::~AppendLog() {
  if (fd_ >= 0) ::close(fd_);
}

void AppendLog::append(const std::string& text) {
  // Checked at every row (fstat, lstat): a hard link made while the run goes on (cp -al of a
  // running run) is broken before this directory's next row, so the copy never receives it, and a
  // file replaced or removed meanwhile (made private by RunDirectory::log_sizes) is opened anew.
  struct stat open_st, path_st;
  if (fd_ >= 0 && (::fstat(fd_, &open_st) != 0 || open_st.st_nlink != 1 || ::lstat(path_.c_str(), &path_st) != 0 ||
                   open_st.st_ino != path_st.st_ino || open_st.st_dev != path_st.st_dev)) {
    ::close(fd_);
    fd_ = -1;
  }
  if (fd_ < 0) fd_ = open_for_update(path_, O_APPEND, true);
  write_all(fd_, text.data(), text.size(), path_);
}

void append_to_file(const fs::path& path, const std::string& text) {
  AppendLog log(path);
  log.append(text);
}

namespace {

std::string not_regular(const fs::path& path, const std::string& kind) {
  return path.string() + " is " + kind + ", not a regular file (a run directory's files are regular files of its own)";
}

// Fills `st` for `fd` (open on `path`); closes it and throws Refusal when it is not a regular file.
template <class Refusal>
void require_regular(int fd, const fs::path& path, struct stat& st) {
  if (::fstat(fd, &st) != 0) {
    const int e = errno;
    ::close(fd);
    throw SystemError("cannot open " + path.string() + ": " + std::strerror(e));
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    throw Refusal(not_regular(path, what_it_is(st.st_mode)));
  }
}

// Replaces `path` by a copy of the `size` bytes that `fd` (open on it) holds: a new inode that no
// other directory shares.
void copy_to_private(int fd, const fs::path& path, std::uint64_t size) {
  AtomicFile copy(path);
  std::string buffer(std::min<std::uint64_t>(size, std::uint64_t{1} << 20), '\0');
  for (std::uint64_t at = 0; at < size;) {
    const ssize_t n =
        ::pread(fd, buffer.data(), std::min<std::uint64_t>(buffer.size(), size - at), static_cast<off_t>(at));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw SystemError("cannot read " + path.string() + ": " + std::strerror(errno));
    if (n == 0) break;  // it shrank meanwhile: the copy holds what there was
    copy.write(buffer.data(), static_cast<std::size_t>(n));
    at += static_cast<std::uint64_t>(n);
  }
  copy.commit();
}

// Opens `path` for reading without following a symlink or blocking on a FIFO; fills `st`. Throws
// StateError ("is missing", not a regular file, unreadable) naming it.
int open_run_file(const fs::path& path, struct stat& st) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    const int e = errno;
    if (e == ENOENT) throw StateError(path.string() + " is missing");
    if (e == ELOOP) throw StateError(not_regular(path, "a symbolic link"));
    if (e == EACCES) throw StateError("cannot read " + path.string() + ": " + std::strerror(e));
    throw SystemError("cannot read " + path.string() + ": " + std::strerror(e));
  }
  require_regular<StateError>(fd, path, st);
  return fd;
}

std::string read_exactly(int fd, const fs::path& path, std::uint64_t size) {
  std::string bytes(size, '\0');
  std::uint64_t at = 0;
  while (at < size) {
    const ssize_t n = ::read(fd, bytes.data() + at, size - at);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const int e = errno;
      ::close(fd);
      throw SystemError("cannot read " + path.string() + ": " + std::strerror(e));
    }
    if (n == 0) break;
    at += static_cast<std::uint64_t>(n);
  }
  ::close(fd);
  bytes.resize(at);
  return bytes;
}

}  // namespace

int open_for_update(const fs::path& path, int flags, bool create) {
  for (int attempt = 0;; ++attempt) {
    const int fd =
        ::open(path.c_str(), O_RDWR | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC | flags | (create ? O_CREAT : 0), 0644);
    if (fd < 0) {
      const int e = errno;
      if (e == ELOOP) throw InputError(not_regular(path, "a symbolic link"));
      if (e == EISDIR) throw InputError(not_regular(path, "a directory"));
      throw SystemError("cannot open " + path.string() + ": " + std::strerror(e));
    }
    struct stat st;
    require_regular<InputError>(fd, path, st);
    if (st.st_nlink <= 1) return fd;
    // Hard-linked (a copy made with cp -al, or a link from elsewhere): the other directory keeps
    // the shared inode as it is, this one gets its own.
    try {
      if (attempt >= 2)
        throw InputError(path.string() + " keeps being hard-linked from elsewhere while qdrun makes it private");
      copy_to_private(fd, path, static_cast<std::uint64_t>(st.st_size));
    } catch (...) {
      ::close(fd);
      throw;
    }
    ::close(fd);
  }
}

void make_private(const fs::path& path) {
  if (exists_nofollow(path)) ::close(open_for_update(path, 0, false));
}

std::string read_run_file(const fs::path& path, std::uint64_t max_bytes) {
  struct stat st;
  const int fd = open_run_file(path, st);
  const auto size = static_cast<std::uint64_t>(st.st_size);
  if (size > max_bytes) {
    ::close(fd);
    throw StateError(path.string() + " is larger (" + std::to_string(size) + " bytes) than its format allows (" +
                     std::to_string(max_bytes) + ")");
  }
  return read_exactly(fd, path, size);
}

std::string read_run_file_prefix(const fs::path& path, std::uint64_t size) {
  struct stat st;
  const int fd = open_run_file(path, st);
  std::string bytes = read_exactly(fd, path, size);
  if (bytes.size() < size)
    throw StateError(path.string() + " is shorter than the checkpoint records (" + std::to_string(size) + " bytes)");
  return bytes;
}

bool exists_nofollow(const fs::path& path) {
  struct stat st;
  return ::lstat(path.c_str(), &st) == 0;
}

void require_replaceable(const fs::path& path) {
  struct stat st;
  if (::lstat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode) && !S_ISLNK(st.st_mode))
    throw InputError(path.string() + " is " + what_it_is(st.st_mode) +
                     ", not a regular file: qdrun writes a new file in its place, and never in place of a "
                     "directory, device, FIFO or socket; move it away or name another file");
}

void require_regular_or_absent(const fs::path& path) {
  struct stat st;
  if (::lstat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode))
    throw InputError(not_regular(path, what_it_is(st.st_mode)));
}

}  // namespace qd::runtime
