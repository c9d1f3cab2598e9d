// Text output helpers: exact number formatting and atomic file replacement.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>

namespace qd::runtime {

// Shortest text that reads back to the same double ("nan" and "inf" spelled as pandas reads them),
// as write_number() (number_format.hpp) writes it.
void append_number(std::string& out, double v);
std::string format_number(double v);
void append_int(std::string& out, std::int64_t v);

// Zeroes the upper halves of the AVX registers (x86 with AVX; a no-op elsewhere). Vectorised code
// can leave them dirty, and then every SSE instruction of code built for generic x86-64, such as
// libstdc++'s number formatting, pays a merge penalty: formatting archive.csv ran 3.5x slower
// (after the checkpoint code, XINUSE showed the AVX upper state in use). append_number() calls it.
void clear_upper_vector_state() noexcept;

// Produces a text of `blocks` consecutive pieces on up to `threads` threads, this one included,
// and hands them to `write` in order on this thread, each as soon as it and the ones before it are
// done. format(b, out) writes piece b at `out` (room for max_block_bytes) and returns its end.
// At most 2 x threads pieces are held at once, so memory stays bounded however long the text. An
// exception from `format` or `write` stops the work and is rethrown once the helpers have stopped.
// archive.csv is formatted this way, spread over the cores that are idle at a loop's end
// (formatting is most of the cost of writing it, see number_format.hpp).
void format_in_order(std::size_t blocks, std::size_t max_block_bytes, unsigned threads,
                     const std::function<char*(std::size_t block, char* out)>& format,
                     const std::function<void(const char* text, std::size_t size)>& write);

// Writes `content` to `path` atomically: a temporary file in the same directory, fsync, rename.
// Readers see either the old file or the new one, never a torn write.
void write_file_atomic(const std::filesystem::path& path, const std::string& content);

// Makes a finished temporary file durable and moves it over `path` (fsync, rename, fsync dir).
void commit_file(const std::filesystem::path& tmp, const std::filesystem::path& path);

// Writes a large file piece by piece to "<path>.tmp" and moves it over `path` on commit(). The
// disk writes of each piece start at once (Linux), so commit()'s fsync does not wait for the
// whole file. Without commit() the temporary file is removed.
class AtomicFile {
 public:
  explicit AtomicFile(std::filesystem::path path);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  void write(const std::string& bytes) { write(bytes.data(), bytes.size()); }
  void write(const char* bytes, std::size_t size);
  void commit();

 private:
  std::filesystem::path path_, tmp_;
  int fd_ = -1;
  std::uint64_t written_ = 0;
};

// A log the run appends rows to, opened on the first append and then kept open. Rows are
// buffered and written at least every kFlushInterval (so `tail -f` follows the run), on flush()
// and on destruction: a write() per row cost 10 µs, 5 % of the framework's overhead on the
// analytic arm. A killed run loses at most the last interval's rows, which --resume would cut
// anyway: the run flushes before each checkpoint, and the checkpoint records the file's size.
class AppendLog {
 public:
  static constexpr std::chrono::seconds kFlushInterval{1};

  explicit AppendLog(std::chrono::steady_clock::duration flush_interval = kFlushInterval)
      : flush_interval_(flush_interval) {}
  ~AppendLog();  // flushes; errors are dropped (nothing to report them to)
  AppendLog(const AppendLog&) = delete;
  AppendLog& operator=(const AppendLog&) = delete;
  void append(const std::filesystem::path& path, const std::string& text);
  void flush();

 private:
  std::chrono::steady_clock::duration flush_interval_;
  std::filesystem::path path_;
  int fd_ = -1;
  std::string pending_;
  std::chrono::steady_clock::time_point last_flush_{};
};

// Appends text and flushes it to the OS (so a killed run keeps every completed row).
void append_to_file(const std::filesystem::path& path, const std::string& text);

}  // namespace qd::runtime
