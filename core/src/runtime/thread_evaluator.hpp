// The "threads" backend: rollouts inside qdrun's process, serially (1 worker) or on local threads
// (worker_pool.hpp). Unsupervised: a crash in plugin code ends qdrun (the process backend is the
// supervised default).
#pragma once

#include "runtime/batch_protocol.hpp"
#include "runtime/evaluator.hpp"
#include "runtime/worker_pool.hpp"

#include <cstdint>
#include <vector>

namespace qd::runtime {

// An environment with persistent worlds gets one row per call, each world's rows in order on one
// thread at a time, the worlds spread over the threads.
class ThreadEvaluator final : public Evaluator {
 public:
  // persistent_worlds: the environment's (info().persistent_worlds), or 0 to run every row as a
  // stateless rollout in a fresh world.
  ThreadEvaluator(const Environment& env, const Descriptor& desc, const PolicyShape& shape, int workers,
                  PluginLabels labels = {}, int persistent_worlds = 0);

  int workers() const noexcept override { return pool_.size(); }
  const char* backend() const noexcept override { return "threads"; }
  void evaluate(const Matrix& params, const std::vector<std::uint64_t>& episode_seeds, std::uint64_t first_episode,
                Evaluations& out) override;

 private:
  // Rows [begin, end) of the batch into their records (world: RolloutBatch::world).
  void evaluate_rows(const Matrix& params, const std::uint64_t* seeds, std::size_t begin, std::size_t end,
                     int world = -1);
  RowEvaluator rows_;
  int worlds_;                   // the environment's persistent worlds (0: stateless)
  std::vector<Trace> traces_;    // one per offspring, reused across batches
  std::vector<double> records_;  // one record per offspring (batch_protocol.hpp)
  WorkerPool pool_;
};

}  // namespace qd::runtime
