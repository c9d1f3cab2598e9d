// Known-answer and statistical tests of the Iso+LineDD mutator (README.md); the partner pairing's
// own tests are in plugins/common/line_dd_ops/test.
#include "iso_line_dd_mutator.hpp"

#include <qd/testing/conformance.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace {

using qd::Rng;
using qd::Stream;

qd::Config config(double iso, double line) {
  qd::Config cfg = qd::defaults_of(qd::line_dd::kIsoLineDdParams, "mutator");
  cfg.set_float("iso_sigma", iso, "test");
  cfg.set_float("line_sigma", line, "test");
  return cfg;
}

// With both sigmas 0 every offspring is exactly its partner: another parent of the batch.
TEST(LineDDMutator, ZeroSigmaOffspringIsThePartner) {
  const qd::BuildContext bctx;
  qd::line_dd::IsoLineDdMutator mutator(config(0.0, 0.0), bctx);
  const std::size_t n = 37, p = 3;
  qd::Parents parents;
  parents.theta.resize(n, p);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t k = 0; k < p; ++k) parents.theta(i, k) = 10.0 * i + k;
  Rng rng(3, Stream::kMutation, 1, 0);
  qd::MutateContext mctx;
  mctx.rng = &rng;
  qd::Offspring out;
  mutator.mutate(parents, n, mctx, out);
  ASSERT_EQ(out.theta.rows(), 37);
  EXPECT_EQ(out.metrics, std::vector<double>{1.0});  // the mixing ratio
  std::vector<int> used(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    const auto partner = static_cast<std::size_t>(out.theta(i, 0) / 10.0);
    ASSERT_NE(partner, i);
    ASSERT_EQ(out.theta.row(i), parents.theta.row(partner));
    ++used[partner];
  }
  for (const int u : used) EXPECT_LE(u, 2);
}

// For the pair (a, b), n = 2 pairs 0 with 1, so offspring 0 ~ N(b, iso² I + line² d dᵀ), d = b − a.
// Estimates from N draws: mean_k has SE sqrt(Σ_kk / N); the sample covariance entry S_jk of a
// Gaussian has variance (Σ_jk² + Σ_jj Σ_kk) / N. Every entry must lie within 5 SE.
TEST(LineDDOperator, MeanAndCovarianceMatchTheFormula) {
  const double iso = 0.01, line = 0.2;  // the defaults
  const qd::BuildContext bctx;
  qd::line_dd::IsoLineDdMutator mutator(config(iso, line), bctx);
  const int p = 4;
  qd::Parents parents;
  parents.theta.resize(2, p);
  parents.theta.row(0) << 0.3, -0.2, 0.5, 1.0;    // a
  parents.theta.row(1) << 0.4, -0.25, 0.52, 1.0;  // b: d = (0.1, -0.05, 0.02, 0)
  const Eigen::RowVector4d a = parents.theta.row(0), b = parents.theta.row(1);
  const Eigen::RowVector4d d = b - a;
  const Eigen::Matrix4d sigma = iso * iso * Eigen::Matrix4d::Identity() + line * line * d.transpose() * d;

  const int draws = 30000;
  Eigen::MatrixXd x0(draws, p), x1(draws, p);
  Rng rng(11, Stream::kMutation, 1, 0);
  qd::MutateContext mctx;
  mctx.rng = &rng;
  qd::Offspring out;
  for (int t = 0; t < draws; ++t) {
    mutator.mutate(parents, 2, mctx, out);
    x0.row(t) = out.theta.row(0);
    x1.row(t) = out.theta.row(1);
  }
  double worst = 0.0;  // largest |estimate − formula| / SE, reported as a test property
  for (const auto* xs : {&x0, &x1}) {
    const Eigen::RowVector4d expected_mean = xs == &x0 ? b : a;  // offspring 1 is centred on a
    const Eigen::RowVector4d mean = xs->colwise().mean();
    const Eigen::MatrixXd centred = xs->rowwise() - mean;
    const Eigen::Matrix4d cov = centred.transpose() * centred / (draws - 1);
    for (int k = 0; k < p; ++k) {
      const double se = std::sqrt(sigma(k, k) / draws);
      EXPECT_NEAR(mean(k), expected_mean(k), 5 * se) << "mean " << k;
      worst = std::max(worst, std::abs(mean(k) - expected_mean(k)) / se);
    }
    for (int j = 0; j < p; ++j)
      for (int k = 0; k < p; ++k) {
        const double se = std::sqrt((sigma(j, k) * sigma(j, k) + sigma(j, j) * sigma(k, k)) / draws);
        EXPECT_NEAR(cov(j, k), sigma(j, k), 5 * se) << "cov " << j << "," << k;
        worst = std::max(worst, std::abs(cov(j, k) - sigma(j, k)) / se);
      }
  }
  RecordProperty("worst_standard_errors", std::to_string(worst));
  // The line term is visible: along d the variance is iso² + line²|d|², 5.2x the isotropic part.
  EXPECT_NEAR(sigma(0, 0), 1e-4 + 4e-4, 1e-15);
}

// The shipped conformance checks (qd/testing), in both pairing modes.
TEST(LineDDMutator, Conforms) {
  for (const char* pairing : {"reference", "swap"}) {
    qd::Config cfg = qd::defaults_of(qd::line_dd::kIsoLineDdParams, "mutator");
    cfg.set_string("pairing", pairing, "test");
    const qd::testing::Report report = qd::testing::check_mutator(
        [&] { return std::make_unique<qd::line_dd::IsoLineDdMutator>(cfg, qd::BuildContext{}); });
    EXPECT_TRUE(report.ok()) << pairing << ": " << report;
  }
}

}  // namespace
