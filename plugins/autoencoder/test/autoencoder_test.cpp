#include "autoencoder.hpp"

#include <qd/errors.hpp>
#include <qd/policy.hpp>
#include <qd/testing/conformance.hpp>
#include <qd/testing/training_log.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace {

using qd::Matrix;
using qd::autoencoder::Autoencoder;
using qd::autoencoder::Hyper;

Hyper small_hyper(bool float64) {
  Hyper h;
  h.hidden = 16;
  h.latent = 4;
  h.float64 = float64;
  h.threads = 1;
  return h;
}

Matrix random_matrix(Eigen::Index rows, Eigen::Index cols, std::uint64_t key, double scale = 1.0) {
  qd::Rng rng(99, qd::Stream::kPlugin, key);
  Matrix m(rows, cols);
  rng.fill_normal(m.data(), static_cast<std::size_t>(m.size()), scale);
  return m;
}

qd::Dataset make_dataset(const Matrix& x, int loop = 0) {
  qd::Dataset d(static_cast<std::size_t>(x.cols()));
  for (Eigen::Index i = 0; i < x.rows(); ++i) d.add(x.row(i).data(), i, loop);
  return d;
}

double relative_error(const Matrix& a, const Matrix& b) {
  return (a - b).norm() / b.norm();
}

TEST(AutoencoderJacobian, ClosedFormMatchesCentralDifferences) {
  const int P = 30;
  Hyper hyper = small_hyper(true);
  hyper.max_epochs = 200;
  hyper.learning_rate = 1e-3;
  Autoencoder ae(hyper, P, 7);
  // Train a little so that the biases are non-zero (both ELU branches, away from the kink).
  ae.fit(make_dataset(random_matrix(40, P, 1)), qd::FitContext{0, 1});
  const Matrix z = random_matrix(5, 4, 2);
  std::vector<Matrix> jac;
  ae.decoder_jacobians(z, jac);
  ASSERT_EQ(jac.size(), 5u);
  const double h = 1e-6;
  for (Eigen::Index i = 0; i < z.rows(); ++i) {
    Matrix fd(P, 4);
    for (int k = 0; k < 4; ++k) {
      Matrix zp = z.row(i), zm = z.row(i), yp, ym;
      zp(0, k) += h;
      zm(0, k) -= h;
      ae.decode(zp, yp);
      ae.decode(zm, ym);
      fd.col(k) = (yp - ym).transpose() / (2 * h);
    }
    ASSERT_EQ(jac[static_cast<std::size_t>(i)].rows(), P);
    ASSERT_EQ(jac[static_cast<std::size_t>(i)].cols(), 4);
    EXPECT_LT(relative_error(jac[static_cast<std::size_t>(i)], fd), 1e-6) << "row " << i;
  }
}

TEST(AutoencoderJacobian, VjpEqualsTransposedJacobianTimesV) {
  const int P = 30;
  Autoencoder ae(small_hyper(true), P, 8);
  const Matrix z = random_matrix(7, 4, 3);
  const Matrix v = random_matrix(7, P, 4);
  std::vector<Matrix> jac;
  ae.decoder_jacobians(z, jac);
  Matrix expected(7, 4), out;
  for (Eigen::Index i = 0; i < 7; ++i) expected.row(i) = v.row(i) * jac[static_cast<std::size_t>(i)];
  ae.decoder_vjp(z, v, out);
  EXPECT_LT(relative_error(out, expected), 1e-10);
}

TEST(AutoencoderTraining, LearnsLowRankData) {
  // N = 512 samples of rank 5 in P = 200. The bound is relative to the data's total variance
  // (per-sample SSE of the best constant predictor, ~ 5 * 200 * 0.2^2 = 40): the untrained
  // network does no better than that (asserted), while a rank-5 model can reach 0. Requiring
  // 1 % of it (a 100x reduction) shows the model found the subspace; 150 epochs x 8 batches at
  // lr 1e-3 reach about 0.35 % here, so the bound leaves a 3x margin.
  const Eigen::Index N = 512, P = 200;
  const Matrix x = random_matrix(N, 5, 10) * random_matrix(5, P, 11, 0.2);
  const double total_variance = (x.rowwise() - x.colwise().mean()).squaredNorm() / static_cast<double>(N);
  Hyper h;
  h.hidden = 32;
  h.latent = 5;
  h.learning_rate = 1e-3;
  h.max_epochs = 150;
  h.threads = 1;
  Autoencoder ae(h, static_cast<int>(P), 3);
  qd::Vector err;
  ae.reconstruction_errors(x, err);
  const double before = err.squaredNorm() / static_cast<double>(N);
  const qd::FitReport r = ae.fit(make_dataset(x), qd::FitContext{0, 5});
  ae.reconstruction_errors(x, err);
  const double after = err.squaredNorm() / static_cast<double>(N);
  EXPECT_EQ(r.epochs, 150);
  EXPECT_TRUE(std::isnan(r.test_loss));
  EXPECT_GT(before, 0.5 * total_variance);
  EXPECT_LT(after, 0.01 * total_variance) << "before " << before << " total variance " << total_variance;
  EXPECT_LT(r.train_loss, 0.01 * total_variance);
  std::printf("low-rank: total variance %.4g, before %.4g, after %.4g\n", total_variance, before, after);
}

TEST(AutoencoderEarlyStop, SlopeIsLeastSquares) {
  std::vector<double> y(100);
  for (int i = 0; i < 100; ++i) y[static_cast<std::size_t>(i)] = 3.0 - 0.25 * i;
  EXPECT_NEAR(qd::autoencoder::loss_slope(y.data(), y.size()), -0.25, 1e-12);
}

// Runs the rule epoch by epoch over `losses`; returns the epoch at which it stops, or -1.
int stop_epoch(const std::vector<double>& losses) {
  std::vector<double> seen;
  for (std::size_t e = 0; e < losses.size(); ++e) {
    seen.push_back(losses[e]);
    if (qd::autoencoder::should_stop(seen, static_cast<int>(e), 100, 1e-5)) return static_cast<int>(e);
  }
  return -1;
}

TEST(AutoencoderEarlyStop, RuleFiresExactlyWhenSpecified) {
  std::vector<double> decreasing(2000), flat(500, 1.0), rising(500), tiny_rise(500), vee(600);
  for (std::size_t i = 0; i < decreasing.size(); ++i) decreasing[i] = 1.0 / (1.0 + static_cast<double>(i));
  for (std::size_t i = 0; i < rising.size(); ++i) rising[i] = 1.0 + 1e-3 * static_cast<double>(i);
  for (std::size_t i = 0; i < tiny_rise.size(); ++i) tiny_rise[i] = 1.0 + 0.5e-5 * static_cast<double>(i);
  EXPECT_EQ(stop_epoch(decreasing), -1);  // strictly decreasing: never
  // Flat: slope 0 < 1e-5, so the reference rule (slope >= 1e-5) never fires.
  EXPECT_EQ(stop_epoch(flat), -1);
  // Rising: fires at the first epoch checked, 101 (the check needs epoch index > 100).
  EXPECT_EQ(stop_epoch(rising), 101);
  EXPECT_EQ(stop_epoch(tiny_rise), -1);  // slope 0.5e-5 is below the threshold
  // Falls by 1e-3 per epoch until epoch 300, then rises by 1e-3. The window ending at e = 349
  // (epochs 250..349) is symmetric about the minimum but for one point, slope < 1e-5; the one
  // ending at 350 has slope 1.5e-5 (numpy.polyfit agrees), so the rule fires at 350.
  for (std::size_t i = 0; i < vee.size(); ++i) vee[i] = 1.0 + 1e-3 * std::abs(static_cast<double>(i) - 300.0);
  EXPECT_EQ(stop_epoch(vee), 350);
}

TEST(AutoencoderAdam, ResetBetweenFits) {
  const int P = 20;
  Hyper h = small_hyper(false);
  h.max_epochs = 3;
  Autoencoder ae(h, P, 4);
  const std::vector<double> initial = ae.model().weights();
  const qd::Dataset d = make_dataset(random_matrix(100, P, 5));  // 2 batches per epoch (64 + 36)
  ae.fit(d, qd::FitContext{0, 1});
  EXPECT_EQ(ae.model().adam_steps(), 6);
  const std::vector<double> after_first = ae.model().weights();
  EXPECT_NE(after_first, initial);
  std::vector<double> moments = ae.model().adam_moments();
  EXPECT_GT(Eigen::Map<const Eigen::VectorXd>(moments.data(), static_cast<Eigen::Index>(moments.size())).norm(), 0.0);

  // A second fit with 0 epochs shows the state at the start of a fit: moments and the step count
  // are reset, the weights are kept.
  Hyper h0 = h;
  h0.max_epochs = 0;
  Autoencoder probe(h0, P, 4);
  std::stringstream blob;
  ae.save(blob);
  probe.load(blob);
  probe.fit(d, qd::FitContext{1, 1});
  EXPECT_EQ(probe.model().adam_steps(), 0);
  moments = probe.model().adam_moments();
  for (double m : moments) ASSERT_EQ(m, 0.0);
  EXPECT_EQ(probe.model().weights(), after_first);

  // And a 3-epoch second fit counts its steps from zero again.
  ae.fit(d, qd::FitContext{0, 1});
  EXPECT_EQ(ae.model().adam_steps(), 6);
}

TEST(AutoencoderTraining, ResultsDoNotDependOnThreadCount) {
  const int P = 150;  // several column chunks of P
  const qd::Dataset d = make_dataset(random_matrix(130, P, 12));
  std::vector<double> weights[3];
  for (int threads = 1; threads <= 3; ++threads) {
    Hyper h = small_hyper(false);
    h.max_epochs = 3;
    h.learning_rate = 1e-3;
    h.threads = threads;
    Autoencoder ae(h, P, 5);
    ae.fit(d, qd::FitContext{1, 9});
    weights[threads - 1] = ae.model().weights();
  }
  EXPECT_EQ(weights[0], weights[1]);
  EXPECT_EQ(weights[0], weights[2]);
}

// Eigen's products block the summed dimension by the L1 size: if it came from the CPU (CPUID), two
// machines with the same instruction set would train different weights (they did: 48 KiB vs 32 KiB
// L1d). The core makes everything that links it use Eigen's fixed default instead.
TEST(AutoencoderTraining, ProductBlockingIgnoresTheMachinesCaches) {
#ifndef EIGEN_NO_CPUID
  FAIL() << "EIGEN_NO_CPUID is not defined: qd::core's compile definitions did not reach this target";
#endif
#if defined(__x86_64__)
  EXPECT_EQ(Eigen::l1CacheSize(), 32 * 1024);
  EXPECT_EQ(Eigen::l2CacheSize(), 256 * 1024);
#endif
}

TEST(AutoencoderState, SaveLoadIsBitExactAndChecksShape) {
  const int P = 25;
  for (bool float64 : {false, true}) {
    Hyper h = small_hyper(float64);
    h.max_epochs = 2;
    h.learning_rate = 1e-3;
    Autoencoder a(h, P, 11);
    a.fit(make_dataset(random_matrix(70, P, 6)), qd::FitContext{0, 2});
    std::stringstream blob;
    a.save(blob);
    Autoencoder b(h, P, 12);  // other seed: other weights until loaded
    b.load(blob);
    EXPECT_EQ(a.model().weights(), b.model().weights());
    EXPECT_EQ(a.model().adam_moments(), b.model().adam_moments());
    EXPECT_EQ(a.model().adam_steps(), b.model().adam_steps());
    const Matrix theta = random_matrix(9, P, 7);
    Matrix za, zb, ya, yb;
    a.encode(theta, za);
    b.encode(theta, zb);
    a.decode(za, ya);
    b.decode(zb, yb);
    EXPECT_TRUE((za.array() == zb.array()).all());
    EXPECT_TRUE((ya.array() == yb.array()).all());

    std::stringstream blob2;
    a.save(blob2);
    const std::string bytes = blob2.str();
    Hyper other = h;
    other.latent = 5;
    Autoencoder wrong_latent(other, P, 1);
    std::stringstream in1(bytes);
    EXPECT_THROW(wrong_latent.load(in1), qd::StateError);
    Autoencoder wrong_params(h, P + 1, 1);
    std::stringstream in2(bytes);
    EXPECT_THROW(wrong_params.load(in2), qd::StateError);
    Hyper other_precision = h;
    other_precision.float64 = !float64;
    Autoencoder wrong_precision(other_precision, P, 1);
    std::stringstream in3(bytes);
    EXPECT_THROW(wrong_precision.load(in3), qd::StateError);
    std::stringstream truncated(bytes.substr(0, bytes.size() / 2));
    EXPECT_THROW(b.load(truncated), qd::StateError);
  }
}

TEST(AutoencoderSplit, ReferenceUsesOldestThirtyPercentAfterLoopZero) {
  qd::Rng rng(1, qd::Stream::kTraining, 0);
  const auto s0 = qd::autoencoder::make_split(10, 0, false, 0.3, rng);
  EXPECT_TRUE(s0.test.empty());
  EXPECT_EQ(s0.train.size(), 10u);
  const auto s1 = qd::autoencoder::make_split(10, 1, false, 0.3, rng);
  EXPECT_EQ(s1.test, (std::vector<Eigen::Index>{0, 1, 2}));
  EXPECT_EQ(s1.train, (std::vector<Eigen::Index>{3, 4, 5, 6, 7, 8, 9}));
  const auto s7 = qd::autoencoder::make_split(17, 7, false, 0.3, rng);  // floor(5.1) = 5
  EXPECT_EQ(s7.test, (std::vector<Eigen::Index>{0, 1, 2, 3, 4}));
  const auto r0 = qd::autoencoder::make_split(10, 0, true, 0.3, rng);  // random: loop 0 too
  EXPECT_EQ(r0.test.size(), 3u);
  EXPECT_EQ(r0.train.size(), 7u);
}

TEST(AutoencoderSplit, FitReportsTestLossOfFirstEntriesAndLogs) {
  const int P = 12;
  const Eigen::Index N = 40;  // test = rows 0..11
  Hyper h = small_hyper(true);
  h.max_epochs = 4;
  h.learning_rate = 1e-3;
  Autoencoder ae(h, P, 21);
  const Matrix x = random_matrix(N, P, 8);
  const qd::Dataset d = make_dataset(x);
  qd::testing::MemoryLog log;

  const qd::FitReport r0 = ae.fit(d, qd::FitContext{0, 3, &log});
  EXPECT_EQ(r0.epochs, 4);
  EXPECT_TRUE(std::isnan(r0.test_loss));
  const qd::FitReport r1 = ae.fit(d, qd::FitContext{1, 3, &log});
  EXPECT_EQ(r1.epochs, 4);
  qd::Vector err;
  ae.reconstruction_errors(x.topRows(12), err);
  EXPECT_NEAR(r1.test_loss, err.squaredNorm() / 12.0, 1e-12 * r1.test_loss);
  ae.reconstruction_errors(x.bottomRows(N - 12), err);
  EXPECT_GT(std::abs(r1.test_loss - err.squaredNorm() / static_cast<double>(N - 12)), 1e-9);

  std::istringstream in(log.text("losses.csv"));
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  ASSERT_EQ(lines.size(), 9u);
  EXPECT_EQ(lines[0], "loop,epoch,train_loss,test_loss");
  EXPECT_EQ(lines[1].rfind("0,0,", 0), 0u);
  EXPECT_EQ(lines[1].back(), ',');  // loop 0: no test loss
  EXPECT_EQ(lines[5].rfind("1,0,", 0), 0u);
  EXPECT_NE(lines[8].back(), ',');
}

TEST(AutoencoderConfig, LatentLargerThanParamsIsAConfigError) {
  qd::Config cfg = qd::defaults_of(qd::autoencoder::kParams, "representation");
  const qd::PolicyShape shape(2, {3}, 1);  // P = 3*3 + 4*1 = 13 < 50
  qd::BuildContext ctx;
  ctx.seed = 1;
  ctx.policy = &shape;
  try {
    Autoencoder ae(cfg, ctx);
    FAIL() << "expected a ConfigError";
  } catch (const qd::ConfigError& e) {
    EXPECT_EQ(e.key(), "latent");
  }
  cfg.set_int("latent", 13, "test");
  Autoencoder ok(cfg, ctx);
  EXPECT_EQ(ok.latent_size(), 13);
}

// The shipped conformance checks (qd/testing) in both precisions, built from the table as the
// core builds the model. float32 arithmetic needs a larger difference step and looser tolerances.
TEST(AutoencoderConformance, Float64AndFloat32) {
  const qd::PolicyShape shape(3, {4}, 2);  // P = 26
  qd::BuildContext ctx;
  ctx.seed = 5;
  ctx.policy = &shape;
  const qd::Dataset data = qd::testing::make_dataset(random_matrix(40, 26, 12));
  for (const char* precision : {"float64", "float32"}) {
    qd::Config cfg = qd::defaults_of(qd::autoencoder::kParams, "representation");
    cfg.set_int("hidden", 16, "test");
    cfg.set_int("latent", 4, "test");
    cfg.set_int("max_epochs", 30, "test");
    cfg.set_float("learning_rate", 1e-3, "test");
    cfg.set_int("threads", 1, "test");
    cfg.set_string("precision", precision, "test");
    qd::testing::RepresentationOptions options;
    if (std::string(precision) == "float32") {
      options.fd_step = 1e-2;
      options.jacobian_tolerance = 1e-2;
      options.vjp_tolerance = 1e-5;
      options.reconstruction_tolerance = 1e-5;
    }
    const qd::testing::Report report =
        qd::testing::check_representation([&] { return std::make_unique<Autoencoder>(cfg, ctx); }, data, options);
    EXPECT_TRUE(report.ok()) << precision << ": " << report;
  }
}

}  // namespace

// --dry-run's training estimate: the epochs each loop is expected to run, and an epoch's time
// scaling with the rows (the probe is timed once, so equal rows give equal seconds exactly).
TEST(AutoencoderEstimate, ExpectedEpochsFollowTheSplitAndEarlyStopping) {
  Hyper h;
  h.max_epochs = 20000;
  h.early_stop_window = 100;
  EXPECT_EQ(qd::autoencoder::expected_epochs(h, 0), 20000);  // no test set in loop 0: no early stop
  EXPECT_EQ(qd::autoencoder::expected_epochs(h, 1), 102);    // the first epoch the rule may stop at, + 1
  h.random_split = true;
  EXPECT_EQ(qd::autoencoder::expected_epochs(h, 0), 102);
  h.max_epochs = 50;
  EXPECT_EQ(qd::autoencoder::expected_epochs(h, 3), 50);
}

TEST(AutoencoderEstimate, SecondsScaleWithRowsAndEpochs) {
  Hyper h = small_hyper(false);
  h.max_epochs = 1000;
  h.early_stop_window = 8;  // later loops: 10 epochs
  const Autoencoder ae(h, 40, 1);
  const std::vector<double> s = ae.estimate_fit_seconds({100, 100, 300, 0});
  ASSERT_EQ(s.size(), 4u);
  for (double v : s) EXPECT_TRUE(std::isfinite(v) && v >= 0);
  EXPECT_GT(s[0], 0.0);
  EXPECT_GT(s[1], 0.0);
  EXPECT_DOUBLE_EQ(s[2], 3 * s[1]);
  EXPECT_EQ(s[3], 0.0);
  // Loop 0 trains 1000 epochs on every row, later loops 10 on 70 % of them: 1000/10/0.7 = 143
  // times as long per row, give or take the test set's evaluation and the timer's noise.
  EXPECT_GT(s[0] / s[1], 20.0);
  EXPECT_TRUE(ae.estimate_fit_seconds({}).empty());
}
