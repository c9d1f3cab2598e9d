// The batch protocol every backend follows: one row evaluator (rollouts, then descriptors, of rows
// of a parameter block, each exception turned into an EvaluationFault naming the component and the
// offspring), the packed per-offspring record it writes, and how a batch is cut into chunks.
//
// The threads backend calls the row evaluator in its threads, the process backend in its worker
// processes, the MPI backend in each rank's worker process; each unpacks the records into the
// Evaluations the loop reads. So a rollout is called, checked and recorded the same way everywhere,
// and every backend gives the same results.
#pragma once

#include "runtime/evaluator.hpp"

#include <qd/descriptor.hpp>
#include <qd/environment.hpp>
#include <qd/policy.hpp>
#include <qd/types.hpp>

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace qd::runtime {

// Rollouts of rows [b.begin, b.end). An exception becomes an EvaluationFault naming the environment
// and the offspring that throws, found by running the rows again one at a time (rollouts are
// deterministic and stateless); `offset` turns the rows of `b` into offspring indices.
void guarded_rollout(const Environment& env, const std::string& label, const RolloutBatch& b, Trace* traces,
                     std::size_t offset);
// describe() of one trace; an exception becomes an EvaluationFault naming the descriptor.
void guarded_describe(const Descriptor& desc, const std::string& label, const Trace& t, std::int64_t* cell,
                      double* values, std::size_t offspring);

// Packed per-offspring record: status, steps, fitness, cell, then the descriptor values, all as
// doubles (status, steps and cell are small integers, exact).
constexpr std::size_t kRecordHead = 4;
inline std::size_t record_width(std::size_t dims) {
  return kRecordHead + dims;
}
// Records of offspring [begin, end) (records[0] is offspring begin's) into `out`, already sized.
void unpack_records(const double* records, std::size_t begin, std::size_t end, std::size_t dims, Evaluations& out);

// Chunks of a batch of n rows for `workers` workers: at most largest_chunk(n, workers) rows, so
// dispatch costs one call per chunk while enough chunks remain for dynamic load balancing (episodes
// differ in length). The process and MPI backends hand them out by guided self-scheduling: a share
// of the rows still unclaimed, at most `largest`, at least 1, so chunks shrink towards the end of a
// batch and no worker is left running a long last chunk while the others idle.
inline std::size_t largest_chunk(std::size_t n, std::size_t workers) {
  return n / (workers * 8) < 1 ? 1 : n / (workers * 8);
}
inline std::size_t guided_chunk(std::size_t remaining, std::size_t workers, std::size_t largest) {
  const std::size_t share = remaining / (4 * workers);
  return share < 1 ? 1 : (share > largest ? largest : share);
}

// Evaluates rows of a parameter block into packed records: the one place a backend calls the
// environment's rollout() and the descriptor's describe().
class RowEvaluator {
 public:
  RowEvaluator(const Environment& env, const Descriptor& desc, const PolicyShape& shape, PluginLabels labels = {});
  std::size_t dims() const noexcept { return dims_; }
  const PolicyShape& shape() const noexcept { return shape_; }
  const PluginLabels& labels() const noexcept { return labels_; }

  // Rows [b.begin, b.end) of `b` (its shape is ignored: this evaluator's is used) -> one record
  // per row, row b.begin's at `records`; `traces` is scratch indexed like the rows of `b`, and
  // `offset` turns them into offspring indices of the batch (for faults). With `current`, rows run
  // one rollout call each and `current` holds what runs (progress_code), so a supervisor can name
  // the offspring and the component that crashed or hung. Thread-safe for disjoint scratch.
  void evaluate(RolloutBatch b, Trace* traces, double* records, std::size_t offset,
                std::atomic<std::uint64_t>* current = nullptr) const;
  // Rows [0, rows) of the row-major block `params` (rows × P) with their seeds -> rows records,
  // with this evaluator's own trace scratch; they are offspring first_row, first_row + 1, ... of
  // the batch.
  void run(const double* params, const std::uint64_t* seeds, std::size_t rows, double* records,
           std::size_t first_row = 0, std::atomic<std::uint64_t>* current = nullptr);

  // `current` while offspring `row` is in rollout() (describing = false) or describe(); 0 = idle.
  static std::uint64_t progress_code(std::size_t row, bool describing) { return 2 * (row + 1) + (describing ? 1 : 0); }

 private:
  const Environment& env_;
  const Descriptor& desc_;
  PolicyShape shape_;
  PluginLabels labels_;
  std::size_t dims_;
  std::vector<Trace> traces_;
};

}  // namespace qd::runtime
