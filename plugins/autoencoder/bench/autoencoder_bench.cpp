// Benchmark of the autoencoder plugin (run by compare_pytorch.sh; never part of the tests).
//
//   autoencoder_bench [--n 5000] [--p 2052] [--epochs 2] [--parents 200] [--sigma 0.1]
//                     [--realistic-n 3000] [--realistic-p 1635] [--realistic-epochs 200] [--realistic-threads 0]
//
// Prints `key value` lines that the script parses:
//   ours_epoch_ms_t1 / _t2         ms per training epoch (best of 3, setup excluded) (N x P U(-1,1), batch 64, float32)
//   ours_offspring_ms              latent offspring of `parents` parents: encode, xi ~ N(0, sigma I_P),
//                                  z' = z + J^T xi (closed-form VJP), decode
//   realistic_*                    one reference loop >= 1 (oldest 30 % test, early stop) on
//                                  realistic-n x realistic-p data
#include "autoencoder.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

namespace {

using Clock = std::chrono::steady_clock;
using qd::autoencoder::Autoencoder;
using qd::autoencoder::Hyper;

double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

qd::Dataset uniform_dataset(int n, int p, std::uint64_t seed) {
  qd::Rng rng(seed, qd::Stream::kPlugin, 1);
  std::vector<double> row(static_cast<std::size_t>(p));
  qd::Dataset d(static_cast<std::size_t>(p));
  for (int i = 0; i < n; ++i) {
    rng.fill_uniform(row.data(), row.size(), -1.0, 1.0);
    d.add(row.data(), i, 0);
  }
  return d;
}

Hyper bench_hyper(int threads, int epochs) {
  Hyper h;  // reference defaults: HD 100, LD 50, lr 1e-5, batch 64, float32
  h.threads = threads;
  h.max_epochs = epochs;
  return h;
}

}  // namespace

int main(int argc, char** argv) {
  int n = 5000, p = 2052, epochs = 2, parents = 200, rn = 3000, rp = 1635, repochs = 200, rthreads = 0;
  double sigma = 0.1;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    const double v = std::atof(argv[i + 1]);
    if (key == "--n")
      n = static_cast<int>(v);
    else if (key == "--p")
      p = static_cast<int>(v);
    else if (key == "--epochs")
      epochs = static_cast<int>(v);
    else if (key == "--parents")
      parents = static_cast<int>(v);
    else if (key == "--sigma")
      sigma = v;
    else if (key == "--realistic-n")
      rn = static_cast<int>(v);
    else if (key == "--realistic-p")
      rp = static_cast<int>(v);
    else if (key == "--realistic-epochs")
      repochs = static_cast<int>(v);
    else if (key == "--realistic-threads")
      rthreads = static_cast<int>(v);
    else {
      std::fprintf(stderr, "unknown option %s\n", argv[i]);
      return 2;
    }
  }

  const qd::Dataset data = uniform_dataset(n, p, 1);
  // ---- training epochs at 1 and 2 threads ----------------------------------------------------
  std::vector<double> weights_by_threads[2];
  for (int threads : {1, 2}) {
    {
      Autoencoder warm(bench_hyper(threads, 1), p, 42);
      warm.fit(data, qd::FitContext{0, 7});  // warm-up epoch (page faults, thread pool)
      weights_by_threads[threads - 1] = warm.model().weights();
    }
    // Per epoch = (fit of `epochs` epochs - fit of 0 epochs) / epochs: a fit also converts the
    // dataset to float once (~15 ms here), which is setup, as building the tensor is for PyTorch.
    // Best of 3 of each: the machine is shared.
    Autoencoder ae(bench_hyper(threads, epochs), p, 42);
    Autoencoder setup_only(bench_hyper(threads, 0), p, 42);
    double best_fit = 1e300, best_setup = 1e300;
    for (int rep = 0; rep < 3; ++rep) {
      auto t0 = Clock::now();
      setup_only.fit(data, qd::FitContext{0, 7});
      best_setup = std::min(best_setup, ms_since(t0));
      t0 = Clock::now();
      ae.fit(data, qd::FitContext{0, 7});
      best_fit = std::min(best_fit, ms_since(t0));
    }
    const double best = (best_fit - best_setup) / epochs;
    std::printf("ours_fit_setup_ms_t%d %.2f\n", threads, best_setup);
    std::printf("ours_epoch_ms_t%d %.2f\n", threads, best);
  }
  std::printf("ours_threads_bitwise_identical %d\n", weights_by_threads[0] == weights_by_threads[1] ? 1 : 0);

  // ---- latent offspring ----------------------------------------------------------------------
  {
    Autoencoder ae(bench_hyper(1, 1), p, 42);
    ae.fit(data, qd::FitContext{0, 7});
    const qd::Matrix theta = data.params().topRows(parents);
    qd::Matrix z, xi(parents, p), step, child;
    double best = 1e300, best_noise = 1e300;
    for (int rep = 0; rep < 5; ++rep) {
      const auto t0 = Clock::now();
      ae.encode(theta, z);
      qd::Rng rng(7, qd::Stream::kMutation, 1, static_cast<std::uint64_t>(rep));
      const auto tn = Clock::now();
      rng.fill_normal(xi.data(), static_cast<std::size_t>(xi.size()), std::sqrt(sigma));  // sigma is a variance
      const double noise = ms_since(tn);
      ae.decoder_vjp(z, xi, step);
      z += step;
      ae.decode(z, child);
      best = std::min(best, ms_since(t0));
      best_noise = std::min(best_noise, noise);
    }
    std::printf("ours_offspring_ms %.3f\n", best);
    std::printf("ours_offspring_noise_ms %.3f\n", best_noise);
    std::printf("ours_offspring_checksum %.6f\n", child.sum());
  }

  // ---- a realistic loop ------------------------------------------------------------------------
  if (repochs > 0) {
    const qd::Dataset real = uniform_dataset(rn, rp, 2);
    Hyper h = bench_hyper(rthreads, repochs);  // 0 = the plugin's default (all cores)
    Autoencoder ae(h, rp, 42);
    const auto t0 = Clock::now();
    const qd::FitReport r = ae.fit(real, qd::FitContext{1, 7});  // loop 1: oldest 30 % test, early stop
    const double ms = ms_since(t0);
    std::printf("realistic_threads %d\n", rthreads);
    std::printf("realistic_epochs %d\n", r.epochs);
    std::printf("realistic_stopped_early %d\n", r.stopped_early ? 1 : 0);
    std::printf("realistic_total_s %.2f\n", ms / 1000.0);
    std::printf("realistic_epoch_ms %.2f\n", ms / r.epochs);
    std::printf("realistic_train_loss %.6g\n", r.train_loss);
    std::printf("realistic_test_loss %.6g\n", r.test_loss);
  }
  return 0;
}
