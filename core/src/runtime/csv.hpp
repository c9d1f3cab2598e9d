// Writing the run's files: numbers as text, whole files replaced atomically, and appended logs.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

namespace qd::runtime {

// Shortest text that reads back to the same double (std::to_chars); NaN is "nan", infinities
// "inf" and "-inf", as pandas reads them.
void append_number(std::string& out, double v);
std::string format_number(double v);
void append_int(std::string& out, std::int64_t v);

// Writes all of `size` bytes to `fd`; throws qd::Error naming `path` on failure.
void write_all(int fd, const char* bytes, std::size_t size, const std::filesystem::path& path);

// Writes `content` to `path` atomically: a temporary file in the same directory, fsync, rename.
// Readers see either the old file or the new one, never a torn write.
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

}  // namespace qd::runtime
