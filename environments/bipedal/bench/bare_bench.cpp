// Bare-loop baseline: the same rollout code as the plugin, with no evaluator, archive or plugin
// loading, so that qdrun's overhead can be measured against it.
//   bipedal_bare_bench <walker|kicker> [episodes]
#include <qd/policy.hpp>
#include <qd/rng.hpp>

#include "bipedal.hpp"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

int main(int argc, char** argv) {
  if (argc < 2 || (std::strcmp(argv[1], "walker") != 0 && std::strcmp(argv[1], "kicker") != 0)) {
    std::fprintf(stderr, "usage: %s <walker|kicker> [episodes]\n", argv[0]);
    return 2;
  }
  const bool walker = std::strcmp(argv[1], "walker") == 0;
  const long episodes = argc > 2 ? std::strtol(argv[2], nullptr, 10) : 100;
  if (episodes <= 0) {
    std::fprintf(stderr, "episodes must be positive\n");
    return 2;
  }
  qd::bipedal::EpisodeOptions options;
  options.task = walker ? qd::bipedal::Task::kWalker : qd::bipedal::Task::kKicker;
  qd::bipedal::warm_up_box2d();

  const qd::PolicyShape shape(qd::bipedal::observation_size(options.task), {32, 32}, qd::bipedal::kActionSize);
  qd::Rng rng(1, qd::Stream::kPlugin, walker ? 1 : 2);
  std::vector<double> theta(shape.param_count());
  qd::Policy policy(shape);
  qd::Trace trace;
  long long total_steps = 0;
  double seconds = 0.0;
  for (long e = 0; e < episodes; ++e) {
    rng.fill_uniform(theta.data(), theta.size(), -1.0, 1.0);  // outside the timed region
    const auto start = std::chrono::steady_clock::now();
    policy.load(theta.data());
    qd::bipedal::run_episode(options, policy, trace);
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    total_steps += trace.steps;
  }
  std::printf("episodes_per_second=%.3f us_per_step=%.3f us_per_episode=%.3f steps=%lld\n",
              static_cast<double>(episodes) / seconds, seconds * 1e6 / static_cast<double>(total_steps),
              seconds * 1e6 / static_cast<double>(episodes), total_steps);
  return 0;
}
