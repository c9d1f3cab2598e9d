// Carries out the archive's deferred parameter copies (Archive::offer_deferred) on a background
// thread (Archive::complete_copies) and releases them on the loop's thread (release_copies), so copying accepted
// policies into the archive overlaps with evaluating the next batch instead of stalling the loop on memory. Batches of
// copies are done in submission order.
#pragma once

#include <qd/archive.hpp>

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <thread>
#include <vector>

namespace qd::runtime {

class RowCopier {
 public:
  explicit RowCopier(Archive& archive);
  ~RowCopier();  // completes every submitted copy first
  RowCopier(const RowCopier&) = delete;
  RowCopier& operator=(const RowCopier&) = delete;

  // Queues one batch of copies; `copies` is swapped for an empty vector with spare capacity.
  void submit(std::vector<Archive::DeferredCopy>& copies);
  // Blocks until at most `in_flight` submitted batches are not yet complete, then releases the
  // completed ones (Archive::release_copies) on the calling thread, which must be the loop's.
  void wait(std::uint64_t in_flight = 0);

 private:
  void work();

  Archive& archive_;
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  std::deque<std::vector<Archive::DeferredCopy>> queue_;
  std::vector<std::vector<Archive::DeferredCopy>> completed_batches_;  // to release
  std::vector<std::vector<Archive::DeferredCopy>> spare_;
  std::uint64_t submitted_ = 0, completed_ = 0;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace qd::runtime
