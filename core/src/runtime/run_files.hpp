// Writing and reading the run's files: whole files replaced atomically, appended logs, and the
// checks that keep a hostile run directory from redirecting or blocking either: a run directory's
// files are regular files of this directory only (never followed through a symlink, never a FIFO
// or device, never written in place while another directory shares their inode).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

namespace qd::runtime {

// Writes all of `size` bytes to `fd`; throws qd::Error naming `path` on failure.
void write_all(int fd, const char* bytes, std::size_t size, const std::filesystem::path& path);

// Writes `content` to `path` atomically: a temporary file in the same directory, fsync, rename.
// Readers see either the old file or the new one, never a torn write. The temporary file is made
// anew (never opened through a symlink someone left in its place); `path` itself is replaced, so a
// hard link or symlink there is never written through. A directory, device, FIFO or socket at
// `path` is refused (require_replaceable).
void write_file_atomic(const std::filesystem::path& path, const std::string& content);

// Writes a large file piece by piece to "<path>.tmp" and moves it over `path` on commit().
// Without commit() the temporary file is removed.
class AtomicFile {
 public:
  explicit AtomicFile(std::filesystem::path path);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  void write(const std::string& bytes) { write_all(fd_, bytes.data(), bytes.size(), tmp_); }
  void write(const char* bytes, std::size_t size) { write_all(fd_, bytes, size, tmp_); }
  void commit();

 private:
  std::filesystem::path path_, tmp_;
  int fd_ = -1;
};

// A log the run appends rows to (metrics.csv, training.csv): opened on the first append and kept
// open; every row is written at once, and a failed write throws.
class AppendLog {
 public:
  explicit AppendLog(std::filesystem::path path) : path_(std::move(path)) {}
  ~AppendLog();
  AppendLog(const AppendLog&) = delete;
  AppendLog& operator=(const AppendLog&) = delete;
  void append(const std::string& text);
  const std::filesystem::path& path() const noexcept { return path_; }

 private:
  std::filesystem::path path_;
  int fd_ = -1;
};

// Appends text to a file in one write (for logs written rarely).
void append_to_file(const std::filesystem::path& path, const std::string& text);

// Opens a file of a run directory to change it in place (append to it, cut it): read-write, created
// if `create`. Refuses (qd::InputError naming it) a symlink, FIFO, device or directory there. A
// file whose inode other directories share (a hard-linked copy of the run, `cp -al`) is first
// replaced by a private copy of itself, so the change never reaches the other directory. Returns
// the descriptor (close-on-exec); throws qd::SystemError when the system refuses.
int open_for_update(const std::filesystem::path& path, int flags, bool create);

// Makes `path` private as open_for_update does, when it exists (nothing when it does not).
void make_private(const std::filesystem::path& path);

// Reads a file of a run directory: a regular file only (a symlink, FIFO or device is refused
// without blocking), at most `max_bytes` (more is refused). Throws qd::StateError naming the file
// ("... is missing" when it does not exist).
std::string read_run_file(const std::filesystem::path& path, std::uint64_t max_bytes);
// Reads the first `size` bytes of a file of a run directory (the part a checkpoint vouches for),
// with the same checks; StateError when it is shorter.
std::string read_run_file_prefix(const std::filesystem::path& path, std::uint64_t size);
// Whether `path` exists as anything (a dangling symlink too), without following it.
bool exists_nofollow(const std::filesystem::path& path);
// Throws qd::InputError naming `path` when a directory, device, FIFO or socket is there: what
// write_file_atomic must not replace (a rename would swap `--traces /dev/null` for a regular file).
// A regular file or a symlink (replaced, never written through) is fine.
void require_replaceable(const std::filesystem::path& path);
// Throws qd::InputError naming `path` when something other than a regular file is there.
void require_regular_or_absent(const std::filesystem::path& path);

}  // namespace qd::runtime
