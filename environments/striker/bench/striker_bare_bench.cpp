// Bare-loop Striker benchmark: the same episode code as the plugin (run_policy_episode), called
// directly with no evaluator, archive or plugin loading, to measure the framework's overhead.
//
//   striker_bare_bench [episodes=2000] [seed=1]
// Parameters are drawn U(-1, 1) (like the paper's initial samples) before the clock starts.
#include "striker_sim.hpp"

#include <qd/policy.hpp>
#include <qd/rng.hpp>
#include <qd/types.hpp>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <string>

int main(int argc, char** argv) {
  const long episodes = argc > 1 ? std::strtol(argv[1], nullptr, 10) : 2000;
  const unsigned long long seed = argc > 2 ? std::strtoull(argv[2], nullptr, 10) : 1ULL;
  if (episodes <= 0) {
    std::fprintf(stderr, "usage: %s [episodes>0] [seed]\n", argv[0]);
    return 2;
  }

  const qd::PolicyShape shape(qd::striker::kObservationSize, {32, 32}, qd::striker::kActionSize);
  qd::Matrix params(episodes, static_cast<Eigen::Index>(shape.param_count()));
  qd::Rng rng(seed, qd::Stream::kPlugin, 0x5354524bULL /* "STRK" */);
  rng.fill_uniform(params.data(), static_cast<std::size_t>(params.size()), -1.0, 1.0);

  qd::striker::warm_up_box2d();
  const qd::striker::Options options;
  qd::Policy policy(shape);
  qd::Trace trace;
  long long steps = 0, not_ok = 0, walls_touched = 0;

  const std::clock_t cpu_start = std::clock();
  const auto start = std::chrono::steady_clock::now();
  for (long i = 0; i < episodes; ++i) {
    qd::striker::run_policy_episode(options, policy, params.row(i).data(), trace);
    steps += trace.steps;
    not_ok += trace.status != qd::EvalStatus::kOk;
    walls_touched += !trace.events.empty();
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  // CPU time too: on a shared machine the wall clock includes time the process was not running.
  const double cpu_seconds = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;

  std::printf("episodes_per_second=%.1f us_per_step=%.3f us_per_episode=%.1f steps=%lld\n", episodes / seconds,
              1e6 * seconds / static_cast<double>(steps), 1e6 * seconds / static_cast<double>(episodes), steps);
  std::fprintf(stderr,
               "episodes=%ld seconds=%.3f cpu_seconds=%.3f cpu_us_per_step=%.3f not_ok=%lld touched_a_wall=%lld\n",
               episodes, seconds, cpu_seconds, 1e6 * cpu_seconds / static_cast<double>(steps), not_ok, walls_touched);
  return 0;
}
