// Framework overhead: evaluations/s of a full qdrun run (selection, mutation, evaluation,
// description, insertion, metrics, checkpoints, the final archive.csv) divided by evaluations/s of a
// bare loop that calls the same environment and policy directly. Same binary, same process.
//
//   qd_framework_overhead EXPERIMENT.toml [--workers N] [--repeat K] [--whole] [--set k=v]...
// The bare loop is single-threaded; the qdrun run uses N workers (default 1). Prints both rates and
// their ratio (with N > 1 the ratio is the parallel speed-up over the bare loop).
//
// Interleaved (default): the bare loop's batches run between the run's iterations, from its
// progress callback, so both sides share the machine's drift. A shared 2-vCPU VM changes speed by
// tens of per cent within seconds (whole runs of the same work differ by up to 25 %), which whole
// runs measured one after the other cannot cancel. The run's time is its wall time minus the bare
// batches'. Every cost of the run stays on its side: a bare batch waits while the run's checkpoint
// is being written may overlap its background disk writes (a few per cent of a loop's time on
// Striker, on the other core). Bare batches evict the run's batch buffer from the cache, which
// only makes the run slower. --whole alternates whole bare loops and whole runs instead.
//
// One worker is by default one supervised worker process (backend=auto); --set
// evaluation.backend=threads measures the unsupervised in-process mode. The run's CPU time
// (cpu_ratio) includes its worker processes'.
#include "runtime/experiment.hpp"
#include "runtime/registry.hpp"
#include "runtime/run.hpp"

#include <qd/policy.hpp>

#include <sys/resource.h>
#include <unistd.h>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

using namespace qd;
using namespace qd::runtime;
namespace fs = std::filesystem;

namespace {
double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// CPU seconds of the whole process (all threads: the run's checkpoint writer counts too).
double process_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// CPU seconds of this process's reaped children (the process backend's workers).
double children_cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_CHILDREN, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

// CPU seconds of the calling thread.
double thread_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t m = v.size() / 2;
  return v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s EXPERIMENT.toml [--workers N] [--repeat K] [--whole] [--set k=v]...\n", argv[0]);
    return 2;
  }
  tune_allocator();  // as qdrun does; it applies to the bare loop and the run alike
  try {
    // Per process, so two benchmarks can run side by side.
    const fs::path out = fs::temp_directory_path() / ("qd_framework_overhead-" + std::to_string(::getpid()));
    fs::remove_all(out);
    Document doc = Document::read(argv[1]);
    int workers = 1, repeat = 3;
    bool whole = false;
    for (int i = 2; i < argc; ++i) {
      const std::string a = argv[i];
      if (a == "--whole")
        whole = true;
      else if (i + 1 >= argc)
        break;
      else if (a == "--set")
        doc.apply_override(argv[++i]);
      else if (a == "--workers")
        workers = std::stoi(argv[++i]);
      else if (a == "--repeat")
        repeat = std::max(1, std::stoi(argv[++i]));
    }
    doc.apply_override("output.dir=\"" + out.string() + "\"");
    doc.apply_override("evaluation.workers=" + std::to_string(workers));
    Registry reg;
    reg.add_search_dir(installed_plugin_dir());
    reg.add_search_dir(build_tree_plugin_dir());
    reg.discover();

    const Experiment ex = resolve(doc, reg);
    const auto total = static_cast<std::uint64_t>(ex.settings.initial_samples) +
                       static_cast<std::uint64_t>(ex.settings.loops - 1) * ex.settings.iterations * ex.settings.batch;

    // When the experiment samples uniformly (ps-uniform), the bare loop evaluates exactly the
    // policies the run will evaluate (same random streams), so episode lengths match too;
    // otherwise it evaluates fresh U(-1, 1) policies.
    const bool same_policies = ex.mutator.type == "uniform" && ex.initial.type == "uniform" &&
                               ex.mutator.config.get_float("low") == -1.0 && ex.mutator.config.get_float("high") == 1.0;
    auto batches = [&] {
      std::vector<std::pair<Rng, std::size_t>> b;  // (stream, batch size) in run order
      if (same_policies) {
        b.emplace_back(Rng(ex.settings.seed, Stream::kInitial, 0),
                       static_cast<std::size_t>(ex.settings.initial_samples));
        for (int loop = 1; loop < ex.settings.loops; ++loop)
          for (int it = 0; it < ex.settings.iterations; ++it)
            b.emplace_back(Rng(ex.settings.seed, Stream::kMutation, static_cast<std::uint64_t>(loop),
                               static_cast<std::uint64_t>(it)),
                           static_cast<std::size_t>(ex.settings.batch));
      } else {
        for (std::uint64_t done = 0, k = 0; done < total; done += static_cast<std::uint64_t>(ex.settings.batch), ++k)
          b.emplace_back(Rng(1, Stream::kPlugin, k), static_cast<std::size_t>(ex.settings.batch));
      }
      return b;
    };

    // Bare loop: the run's own environment object and policy shape, one rollout call per batch,
    // no evaluator, descriptor, archive or files. Its buffers live across repetitions, as the
    // run's do within a run.
    struct Bare {
      std::vector<std::pair<Rng, std::size_t>> batches;
      std::size_t next = 0;
      std::uint64_t evaluations = 0, steps = 0;
      double seconds = 0, cpu = 0;
      Matrix params;
      std::vector<Trace> traces;
      std::vector<std::uint64_t> seeds;
    } bare;
    auto bare_batch = [&](const Run& run) {
      auto& [rng, n] = bare.batches[bare.next++];
      const PolicyShape& shape = run.components().shape;
      bare.params.resize(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(shape.param_count()));
      bare.traces.resize(n);
      bare.seeds.assign(n, 0);
      rng.fill_uniform(bare.params.data(), static_cast<std::size_t>(bare.params.size()), -1.0, 1.0);
      RolloutBatch b{&shape, bare.params.data(), bare.seeds.data(), 0, n};
      run.components().environment->rollout(b, bare.traces.data());
      for (std::size_t i = 0; i < n; ++i) bare.steps += static_cast<std::uint64_t>(bare.traces[i].steps);
      bare.evaluations += n;
    };
    // Runs bare batches while `more()`, adding their wall and this thread's CPU time to bare's.
    auto bare_batches = [&](const Run& run, auto&& more) {
      const double c0 = thread_cpu_seconds();
      const auto t0 = std::chrono::steady_clock::now();
      while (bare.next < bare.batches.size() && more()) bare_batch(run);
      bare.seconds += seconds_since(t0);
      bare.cpu += thread_cpu_seconds() - c0;
    };
    auto reset_bare = [&] {
      bare.batches = batches();
      bare.next = 0;
      bare.evaluations = bare.steps = 0;
      bare.seconds = bare.cpu = 0;
    };

    std::printf("# %s: %s\n", argv[1],
                whole ? "whole bare loops and whole runs alternate; best of each side"
                      : "bare batches interleaved with the run's iterations; median of the repetitions");
    double best_bare = 1e300, best_run = 1e300, best_bare_cpu = 1e300, best_run_cpu = 1e300;
    std::size_t params_count = 0;
    std::uint64_t bare_steps = 0;
    std::vector<double> ratios, bare_times, run_times, cpu_ratios;
    for (int r = 0; r < repeat; ++r) {
      const fs::path dir = out / ("rep-" + std::to_string(r));
      reset_bare();
      RunOptions opt;
      opt.directory = dir.string();
      const Run* running = nullptr;
      if (!whole)
        opt.on_progress = [&](const Progress& p) {
          bare_batches(*running, [&] { return bare.evaluations < p.evaluations; });
        };
      const double children0 = children_cpu_seconds();
      double run_s = 0, run_cpu = 0;
      {
        Run run(ex, reg, std::move(opt));
        running = &run;
        params_count = run.components().shape.param_count();
        run.create_directory();
        if (whole) bare_batches(run, [] { return true; });
        const double c_run = process_cpu_seconds(), bare_s0 = bare.seconds, bare_cpu0 = bare.cpu;
        const auto t_run = std::chrono::steady_clock::now();
        run.run();
        // Minus the bare batches run from within the run.
        run_s = seconds_since(t_run) - (bare.seconds - bare_s0);
        run_cpu = process_cpu_seconds() - c_run - (bare.cpu - bare_cpu0);
        bare_batches(run, [] { return true; });  // the rest (none unless a checkpoint held them back)
      }
      // Worker processes are reaped when the run ends: their CPU time is the rollouts' (and the
      // descriptors') outside qdrun's process, to compare with the bare loop's.
      const double workers_cpu = children_cpu_seconds() - children0;
      bare_steps = bare.steps;
      best_bare = std::min(best_bare, bare.seconds);
      best_run = std::min(best_run, run_s);
      best_bare_cpu = std::min(best_bare_cpu, bare.cpu);
      best_run_cpu = std::min(best_run_cpu, run_cpu + workers_cpu);
      ratios.push_back(bare.seconds / run_s);
      cpu_ratios.push_back(bare.cpu / (run_cpu + workers_cpu));
      bare_times.push_back(bare.seconds);
      run_times.push_back(run_s);
      std::printf(
          "  repetition %d: bare %.3f s (cpu %.3f), qdrun %.3f s (cpu %.3f, worker processes' cpu %.3f), ratio %.4f "
          "(cpu %.4f)\n",
          r + 1, bare.seconds, bare.cpu, run_s, run_cpu, workers_cpu, bare.seconds / run_s,
          bare.cpu / (run_cpu + workers_cpu));
      std::fflush(stdout);
      fs::remove_all(dir);
    }
    const double n = static_cast<double>(total);
    std::printf(
        "experiment=%s params=%zu evaluations=%llu workers=%d backend=%s same_policies=%d "
        "bare_us_per_step=%.3f\n",
        argv[1], params_count, static_cast<unsigned long long>(total), workers, to_string(ex.settings.backend),
        same_policies ? 1 : 0, 1e6 * best_bare / static_cast<double>(bare_steps));
    if (whole) {
      std::printf(
          "bare_loop_evals_per_s=%.1f qdrun_evals_per_s=%.1f ratio=%.4f bare_us_per_eval=%.2f qdrun_us_per_eval=%.2f "
          "cpu_ratio=%.4f (best of %d alternating repetitions) median_repetition_ratio=%.4f\n",
          n / best_bare, n / best_run, best_bare / best_run, 1e6 * best_bare / n, 1e6 * best_run / n,
          best_bare_cpu / best_run_cpu, repeat, median(ratios));
    } else {
      const auto [lo, hi] = std::minmax_element(ratios.begin(), ratios.end());
      std::printf(
          "bare_loop_evals_per_s=%.1f qdrun_evals_per_s=%.1f ratio=%.4f min_ratio=%.4f max_ratio=%.4f "
          "bare_us_per_eval=%.2f qdrun_us_per_eval=%.2f cpu_ratio=%.4f (median of %d interleaved repetitions; "
          "rates from the median times)\n",
          n / median(bare_times), n / median(run_times), median(ratios), *lo, *hi, 1e6 * median(bare_times) / n,
          1e6 * median(run_times) / n, median(cpu_ratios), repeat);
    }
    fs::remove_all(out);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
