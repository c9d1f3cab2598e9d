#include "runtime/thread_evaluator.hpp"

#include <qd/errors.hpp>

#include <algorithm>

namespace qd::runtime {

ThreadEvaluator::ThreadEvaluator(const Environment& env, const Descriptor& desc, const PolicyShape& shape, int workers,
                                 PluginLabels labels, int persistent_worlds)
    : rows_(env, desc, shape, std::move(labels)), worlds_(persistent_worlds), pool_(workers) {}

void ThreadEvaluator::evaluate_rows(const Matrix& params, const std::uint64_t* seeds, std::size_t begin,
                                    std::size_t end, int world) {
  RolloutBatch b;
  b.params = params.data();
  b.episode_seeds = seeds;
  b.begin = begin;
  b.end = end;
  b.world = world;
  rows_.evaluate(b, traces_.data(), records_.data() + begin * record_width(rows_.dims()), 0);
}

void ThreadEvaluator::evaluate(const Matrix& params, const std::vector<std::uint64_t>& seeds,
                               std::uint64_t first_episode, Evaluations& out) {
  const auto n = static_cast<std::size_t>(params.rows());
  QD_CHECK(seeds.size() == n, "one episode seed per row");
  out.reset(n, rows_.dims());
  if (traces_.size() < n) traces_.resize(n);
  records_.resize(n * record_width(rows_.dims()));
  if (worlds_ > 0) {
    // Episode e runs in world e mod N: row i's world is (first_episode + i) mod N, and a world's
    // rows run in order on whichever thread takes that world, so nothing depends on the threads.
    const auto worlds = static_cast<std::size_t>(worlds_);
    const std::size_t busy = std::min(worlds, n);
    pool_.run(busy, [&](std::size_t k) {
      const std::size_t world = (first_episode + k) % worlds;  // the world of row k, k < busy
      for (std::size_t i = k; i < n; i += worlds)
        evaluate_rows(params, seeds.data(), i, i + 1, static_cast<int>(world));
    });
  } else {
    // With one worker the whole batch is one call.
    const std::size_t workers = static_cast<std::size_t>(pool_.size());
    const std::size_t chunk = workers == 1 ? std::max<std::size_t>(n, 1) : largest_chunk(n, workers);
    const std::size_t chunks = (n + chunk - 1) / chunk;
    pool_.run(chunks, [&](std::size_t c) {
      const std::size_t begin = c * chunk;
      evaluate_rows(params, seeds.data(), begin, std::min(n, begin + chunk));
    });
  }
  unpack_records(records_.data(), 0, n, rows_.dims(), out);
}

}  // namespace qd::runtime
