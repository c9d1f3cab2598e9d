// Writes checkpoints on a background thread, so the loop does not wait for the disk.
//
// At a loop boundary the loop serialises its small state into buffers and starts a capture of
// the archive's changed slots (Archive::begin_capture), then hands the job over; this thread
// copies the captured slots (Job::prepare), appends what is new since the last checkpoint to the append-only files (the
// dataset rows, the archive slots written since), then writes, fsyncs and renames `checkpoint.bin`. At most one
// checkpoint is in flight: the next submit() (and wait()) first waits for the previous one. A checkpoint that was not
// committed when the process died is simply absent, and resume continues from the one before, which is equally
// bit-identical (the logs are cut back to the sizes that checkpoint recorded).
#pragma once

#include <condition_variable>
#include <cstdint>
#include <exception>
#include <filesystem>
#include <functional>
#include <mutex>
#include <streambuf>
#include <string>
#include <thread>
#include <vector>

namespace qd::runtime {

// A stream buffer that appends to a std::string, so state can be serialised with the components'
// save(std::ostream&) into a buffer whose capacity is kept from one checkpoint to the next.
class StringAppender : public std::streambuf {
 public:
  explicit StringAppender(std::string& out) : out_(out) {}

 protected:
  std::streamsize xsputn(const char* s, std::streamsize n) override {
    out_.append(s, static_cast<std::size_t>(n));
    return n;
  }
  int_type overflow(int_type c) override {
    if (!traits_type::eq_int_type(c, traits_type::eof())) out_.push_back(traits_type::to_char_type(c));
    return traits_type::not_eof(c);
  }

 private:
  std::string& out_;
};

class CheckpointWriter {
 public:
  // Bytes for an append-only file: written at `offset`, its committed size so far. Anything past
  // the offset comes from a checkpoint that never committed and is cut away first. `bytes` go
  // first, then `more_size` bytes at `more` (a buffer the caller keeps, filled by `prepare`).
  //
  // `direct`: a whole new file (offset 0, no `bytes`) whose `more` is aligned to kDirectAlignment
  // and readable up to the next multiple of it. It is written with O_DIRECT, bypassing the page
  // cache: copying ~28 MB per loop into it was 60 % of the writer's CPU time on the analytic arm,
  // work that slowed the loop on the other core. Where the file system refuses O_DIRECT the
  // ordinary path is taken.
  static constexpr std::size_t kDirectAlignment = 4096;
  struct Append {
    std::filesystem::path path;
    std::uint64_t offset = 0;
    std::string bytes;
    const char* more = nullptr;
    std::size_t more_size = 0;
    bool direct = false;
  };
  struct Job {
    std::function<void()> prepare;                    // runs on the writer thread before anything is written
    std::filesystem::path checkpoint;                 // final path; written via "<path>.tmp"
    std::string state;                                // checkpoint bytes
    std::vector<Append> appends;                      // made durable before the checkpoint is committed
    std::vector<std::filesystem::path> remove_after;  // files the new checkpoint no longer needs
  };

  // `direct_io` false writes direct appends through the page cache too (tests of that path).
  explicit CheckpointWriter(bool direct_io = true);
  ~CheckpointWriter();  // waits for the checkpoint in flight (errors are dropped: nothing to report to)
  CheckpointWriter(const CheckpointWriter&) = delete;
  CheckpointWriter& operator=(const CheckpointWriter&) = delete;

  // Waits for the previous job, rethrows its error if it failed, then queues this one. The
  // buffers in `job` are swapped out, so the caller can reuse their capacity next time.
  void submit(Job& job);
  // Waits until nothing is in flight; rethrows the error of a failed write.
  void wait();
  // Whether a checkpoint is being written now (it will be done by the time wait() returns).
  bool busy() const;

 private:
  void work();
  void write(const Job& job) const;

  const bool direct_io_;
  mutable std::mutex mutex_;
  std::condition_variable wake_, idle_;
  Job job_;
  bool pending_ = false, stop_ = false;
  std::exception_ptr error_;
  std::thread thread_;
};

}  // namespace qd::runtime
