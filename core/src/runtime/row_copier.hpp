// Carries out the archive's deferred parameter copies (Archive::offer_deferred) on a background
// thread (Archive::complete_copies) and releases them on the loop's thread (release_copies), so
// copying accepted policies into the archive overlaps with evaluation (of the rest of the batch
// when the evaluator streams rows, else of the next batch) instead of stalling the loop on memory.
// Batches of copies complete in submission order.
//
// Waking a blocked thread costs the waker an inter-processor interrupt: 32 µs per submit() on a
// 2-vCPU KVM guest, 0.16 s per 10^6 evaluations of the analytic arm (bench/framework_overhead).
// So with `poll` (a core is left free by the evaluators) the copier does not block while batches
// keep coming: it checks the queue kPollsPerBatch times per batch (the interval between the loop's
// wait() calls), on its own timer, and blocks only after kIdleTimeout without work, after which
// submit() wakes it. What is still queued when the loop needs its buffer back, wait() copies on
// the loop's thread. Polling once per streamed part instead (every 50 µs on the arm) cost the
// copier 2.5 s of CPU per 600 000 evaluations against 0.7 s, and the loop about 0.5 % (interleaved
// medians 0.954 against 0.959, 7 repetitions each). Without `poll` every core runs an evaluator,
// which frequent polls would preempt, and submit() wakes the copier each time.
#pragma once

#include <qd/archive.hpp>

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <thread>
#include <vector>

namespace qd::runtime {

class RowCopier {
 public:
  static constexpr int kPollsPerBatch = 2;
  static constexpr std::chrono::microseconds kMinPoll{50}, kMaxPoll{2000};
  static constexpr std::chrono::milliseconds kIdleTimeout{20};

  RowCopier(Archive& archive, bool poll);
  ~RowCopier();  // completes every submitted copy first
  RowCopier(const RowCopier&) = delete;
  RowCopier& operator=(const RowCopier&) = delete;

  // Queues one batch of copies; `copies` is swapped for an empty vector with spare capacity.
  void submit(std::vector<Archive::DeferredCopy>& copies);
  // Returns when at most `in_flight` submitted batches are not yet complete, copying queued
  // batches on the calling thread rather than waiting for the copier, then releases the completed
  // ones (Archive::release_copies). The calling thread must be the loop's.
  void wait(std::uint64_t in_flight = 0);

 private:
  void work();
  // Copies the oldest queued batch if no batch is being copied, so batches complete in order.
  // Called with `lock` held; returns false when there was nothing it could take.
  bool copy_next(std::unique_lock<std::mutex>& lock);

  Archive& archive_;
  const bool poll_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::vector<Archive::DeferredCopy>> queue_;
  std::vector<std::vector<Archive::DeferredCopy>> completed_batches_;  // to release
  std::vector<std::vector<Archive::DeferredCopy>> spare_;
  std::uint64_t submitted_ = 0, completed_ = 0;
  std::chrono::steady_clock::time_point last_wait_{};
  std::chrono::steady_clock::duration poll_interval_ = kMinPoll;  // the copier's sleep between polls
  bool copying_ = false;                                          // a batch is being copied, by either thread
  bool blocked_ = false;                                          // the copier waits on wake_
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace qd::runtime
