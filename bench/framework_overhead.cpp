// Framework overhead: evaluations/s of a full qdrun run (selection, mutation, evaluation,
// description, insertion, metrics, checkpoints) divided by evaluations/s of a bare loop that calls
// the same environment and policy directly. Same binary, same process, one worker.
//
//   qd_framework_overhead EXPERIMENT.toml [--workers N] [--set k=v]...
// The bare loop is single-threaded; the qdrun run uses N workers (default 1). Prints both rates and
// their ratio (with N > 1 the ratio is the parallel speed-up over the bare loop).
#include "runtime/experiment.hpp"
#include "runtime/registry.hpp"
#include "runtime/run.hpp"

#include <qd/policy.hpp>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

using namespace qd;
using namespace qd::runtime;
namespace fs = std::filesystem;

namespace {
double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s EXPERIMENT.toml [--set k=v]...\n", argv[0]);
    return 2;
  }
  try {
    const fs::path out = fs::temp_directory_path() / "qd_framework_overhead";
    fs::remove_all(out);
    Document doc = Document::read(argv[1]);
    int workers = 1;
    for (int i = 2; i + 1 < argc; i += 2) {
      if (std::string(argv[i]) == "--set") doc.apply_override(argv[i + 1]);
      if (std::string(argv[i]) == "--workers") workers = std::stoi(argv[i + 1]);
    }
    doc.apply_override("output.dir=\"" + out.string() + "\"");
    doc.apply_override("evaluation.workers=" + std::to_string(workers));
    Registry reg;
    reg.add_search_dir(installed_plugin_dir());
    reg.add_search_dir(build_tree_plugin_dir());
    reg.discover();

    Experiment ex = resolve(doc, reg);
    const auto total = static_cast<std::uint64_t>(ex.settings.initial_samples) +
                       static_cast<std::uint64_t>(ex.settings.loops - 1) * ex.settings.iterations * ex.settings.batch;
    Run run(ex, reg, RunOptions{});
    run.create_directory();

    // Bare loop first (warms caches the same way for both): the same environment object, the same
    // policy shape, uniform random parameters, one rollout call per batch of `batch` episodes.
    const PolicyShape& shape = run.policy_shape();
    const auto batch = static_cast<std::size_t>(ex.settings.batch);
    Matrix params(static_cast<Eigen::Index>(batch), static_cast<Eigen::Index>(shape.param_count()));
    Rng rng(1, Stream::kPlugin);
    std::vector<std::uint64_t> seeds(batch, 0);
    std::vector<Trace> traces(batch);
    std::uint64_t bare_evals = 0;
    const auto t_bare = std::chrono::steady_clock::now();
    while (bare_evals < total) {
      rng.fill_uniform(params.data(), static_cast<std::size_t>(params.size()), -1.0, 1.0);
      RolloutBatch b{&shape, &params, seeds.data(), 0, batch};
      run.environment().rollout(b, traces.data());
      bare_evals += batch;
    }
    const double bare_s = seconds_since(t_bare);

    const auto t_run = std::chrono::steady_clock::now();
    run.run();
    const double run_s = seconds_since(t_run);

    const double bare_rate = static_cast<double>(bare_evals) / bare_s;
    const double run_rate = static_cast<double>(total) / run_s;
    std::printf("experiment=%s params=%zu evaluations=%llu workers=%d\n", argv[1], shape.param_count(),
                static_cast<unsigned long long>(total), workers);
    std::printf("bare_loop_evals_per_s=%.1f qdrun_evals_per_s=%.1f ratio=%.4f bare_us_per_eval=%.2f qdrun_us_per_eval=%.2f\n",
                bare_rate, run_rate, run_rate / bare_rate, 1e6 / bare_rate, 1e6 / run_rate);
    fs::remove_all(out);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
