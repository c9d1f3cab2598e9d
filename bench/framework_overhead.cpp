// Framework overhead: evaluations/s of a full qdrun run (selection, mutation, evaluation,
// description, insertion, metrics, checkpoints) divided by evaluations/s of a bare loop that calls
// the same environment and policy directly. Same binary, same process, one worker.
//
//   qd_framework_overhead EXPERIMENT.toml [--workers N] [--run-first] [--set k=v]...
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
  tune_allocator();  // as qdrun does; it applies to the bare loop and the run alike
  try {
    const fs::path out = fs::temp_directory_path() / "qd_framework_overhead";
    fs::remove_all(out);
    Document doc = Document::read(argv[1]);
    int workers = 1;
    for (int i = 2; i + 1 < argc; ++i) {
      if (std::string(argv[i]) == "--set")
        doc.apply_override(argv[++i]);
      else if (std::string(argv[i]) == "--workers")
        workers = std::stoi(argv[++i]);
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

    // Bare loop first: the same environment object and policy shape, one rollout call per batch.
    // When the experiment samples uniformly (ps-uniform), the bare loop evaluates exactly the
    // policies the run will evaluate (same random streams), so episode lengths match too;
    // otherwise it evaluates fresh U(-1, 1) policies.
    const PolicyShape& shape = run.policy_shape();
    const bool same_policies = ex.mutator.type == "uniform" && ex.initial.type == "uniform" &&
                               ex.mutator.config.get_float("low") == -1.0 && ex.mutator.config.get_float("high") == 1.0;
    const auto P = static_cast<Eigen::Index>(shape.param_count());
    std::vector<std::pair<Rng, std::size_t>> batches;  // (stream, batch size) in run order
    if (same_policies) {
      batches.emplace_back(Rng(ex.settings.seed, Stream::kInitial, 0),
                           static_cast<std::size_t>(ex.settings.initial_samples));
      for (int loop = 1; loop < ex.settings.loops; ++loop)
        for (int it = 0; it < ex.settings.iterations; ++it)
          batches.emplace_back(Rng(ex.settings.seed, Stream::kMutation, static_cast<std::uint64_t>(loop),
                                   static_cast<std::uint64_t>(it)),
                               static_cast<std::size_t>(ex.settings.batch));
    } else {
      for (std::uint64_t done = 0, k = 0; done < total; done += static_cast<std::uint64_t>(ex.settings.batch), ++k)
        batches.emplace_back(Rng(1, Stream::kPlugin, k), static_cast<std::size_t>(ex.settings.batch));
    }
    std::uint64_t bare_evals = 0, bare_steps = 0;
    Matrix params;
    std::vector<Trace> traces;
    std::vector<std::uint64_t> seeds;
    bool run_first = false;
    for (int i = 2; i < argc; ++i)
      if (std::string(argv[i]) == "--run-first") run_first = true;
    double run_s = 0;
    auto timed_run = [&] {
      const auto t_run = std::chrono::steady_clock::now();
      run.run();
      run_s = seconds_since(t_run);
    };
    if (run_first) timed_run();
    const auto t_bare = std::chrono::steady_clock::now();
    for (auto& [rng, n] : batches) {
      params.resize(static_cast<Eigen::Index>(n), P);
      traces.resize(n);
      seeds.assign(n, 0);
      rng.fill_uniform(params.data(), static_cast<std::size_t>(params.size()), -1.0, 1.0);
      RolloutBatch b{&shape, &params, seeds.data(), 0, n};
      run.environment().rollout(b, traces.data());
      bare_evals += n;
      for (const auto& t : traces) bare_steps += static_cast<std::uint64_t>(t.steps);
    }
    const double bare_s = seconds_since(t_bare);

    if (!run_first) timed_run();

    const double bare_rate = static_cast<double>(bare_evals) / bare_s;
    const double run_rate = static_cast<double>(total) / run_s;
    std::printf("experiment=%s params=%zu evaluations=%llu workers=%d same_policies=%d bare_us_per_step=%.3f\n",
                argv[1], shape.param_count(), static_cast<unsigned long long>(total), workers, same_policies ? 1 : 0,
                1e6 * bare_s / static_cast<double>(bare_steps));
    std::printf(
        "bare_loop_evals_per_s=%.1f qdrun_evals_per_s=%.1f ratio=%.4f bare_us_per_eval=%.2f qdrun_us_per_eval=%.2f\n",
        bare_rate, run_rate, run_rate / bare_rate, 1e6 / bare_rate, 1e6 / run_rate);
    fs::remove_all(out);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
