// Numerical tests of the PoMS mutators: the latent covariance against its formula, the H/L split
// rules, the no-jacobian latent std, determinism.
#include "poms.hpp"

#include <qd/dataset.hpp>
#include <qd/errors.hpp>
#include <qd/rng.hpp>
#include <qd/testing/conformance.hpp>
#include <qd/testing/elites.hpp>
#include <qd/testing/linear_model.hpp>

#include <gtest/gtest.h>

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

namespace {

using qd::Matrix;
using qd::RowVector;
using qd::Vector;
using qd::poms::NoJacobianMutator;
using qd::poms::PomsMutator;
using qd::poms::SigmaMeaning;
using qd::poms::ThresholdMode;

Matrix gaussian(Eigen::Index rows, Eigen::Index cols, std::uint64_t key, double scale = 1.0) {
  qd::Rng rng(1234, qd::Stream::kPlugin, key);
  Matrix m(rows, cols);
  rng.fill_normal(m.data(), static_cast<std::size_t>(m.size()), scale);
  return m;
}

// A fixed random model with a non-constant Jacobian: linear encoder z = (θ − c)Eᵀ and a
// one-hidden-layer ELU decoder θ = elu(z W1ᵀ + b1) W2ᵀ + b2, so J(z) = W2 diag(elu'(a)) W1.
class EluModel final : public qd::Representation {
 public:
  EluModel(int latent, int hidden, int params)
      : e_(gaussian(latent, params, 1, 0.5)),
        c_(gaussian(1, params, 2)),
        w1_(gaussian(hidden, latent, 3)),
        b1_(gaussian(1, hidden, 4)),
        w2_(gaussian(params, hidden, 5)),
        b2_(gaussian(1, params, 6)) {
    // Latent directions 0 and 1 drive nearly the same hidden units, so JᵀJ has a strong
    // off-diagonal term by construction, whatever the random draws.
    if (latent > 1) w1_.col(1) = w1_.col(0) + 0.3 * w1_.col(1);
  }

  int latent_size() const noexcept override { return static_cast<int>(w1_.cols()); }
  qd::FitReport fit(const qd::Dataset&, const qd::FitContext&) override { return {}; }
  void encode(const Matrix& theta, Matrix& z) const override {
    z.noalias() = (theta.rowwise() - RowVector(c_.row(0))) * e_.transpose();
  }
  void decode(const Matrix& z, Matrix& theta) const override {
    const Matrix h = pre(z).unaryExpr([](double a) { return a > 0.0 ? a : std::expm1(a); });
    theta.noalias() = h * w2_.transpose();
    theta.rowwise() += RowVector(b2_.row(0));
  }
  void decoder_jacobians(const Matrix& z, std::vector<Matrix>& jac) const override {
    const Matrix slope = pre(z).unaryExpr([](double a) { return a > 0.0 ? 1.0 : std::exp(a); });
    jac.resize(static_cast<std::size_t>(z.rows()));
    for (Eigen::Index i = 0; i < z.rows(); ++i)
      jac[static_cast<std::size_t>(i)] = w2_ * slope.row(i).transpose().asDiagonal() * w1_;
  }
  // Row form of Jᵀv: ((v W2) ⊙ elu'(a)) W1.
  void decoder_vjp(const Matrix& z, const Matrix& v, Matrix& out) const override {
    ++vjp_calls;
    const Matrix slope = pre(z).unaryExpr([](double a) { return a > 0.0 ? 1.0 : std::exp(a); });
    out.noalias() = (Matrix(v * w2_).array() * slope.array()).matrix() * w1_;
  }
  void save(std::ostream&) const override {}
  void load(std::istream&) override {}

  mutable int vjp_calls = 0;

 private:
  Matrix pre(const Matrix& z) const {
    Matrix a = z * w1_.transpose();
    a.rowwise() += RowVector(b1_.row(0));
    return a;
  }
  Matrix e_, c_, w1_, b1_, w2_, b2_;
};

// Archive whose stored errors have the given mean (two elites, errors 2m − x and x).
qd::testing::Elites archive_with_mean(std::size_t params, double a, double b) {
  qd::testing::Elites archive(10, params, 1);
  const std::vector<double> theta(params, 0.0);
  archive.add(0, theta, a).add(1, theta, b);
  return archive;
}

qd::Parents parents_of(const Matrix& theta, std::vector<double> errors) {
  qd::Parents parents;
  parents.theta = theta;
  parents.recn_error = Eigen::Map<Vector>(errors.data(), static_cast<Eigen::Index>(errors.size()));
  for (Eigen::Index i = 0; i < theta.rows(); ++i) parents.cells.push_back(i);
  return parents;
}

qd::Offspring run(qd::Mutator& mutator, const qd::Parents& parents, const qd::Representation& rep, int loop,
                  int iteration, const qd::ArchiveView& archive) {
  qd::Rng rng(77, qd::Stream::kMutation, static_cast<std::uint64_t>(loop), static_cast<std::uint64_t>(iteration));
  qd::MutateContext ctx;
  ctx.loop = loop;
  ctx.iteration = iteration;
  ctx.rng = &rng;
  ctx.representation = &rep;
  ctx.archive = &archive;
  qd::Offspring out;
  mutator.mutate(parents, static_cast<std::size_t>(parents.theta.rows()), ctx, out);
  return out;
}

void begin(qd::Mutator& mutator, const qd::ArchiveView& archive, const qd::Representation& rep,
           const qd::Dataset* dataset = nullptr) {
  qd::LoopContext ctx;
  ctx.loop = 1;
  ctx.archive = &archive;
  ctx.dataset = dataset;
  ctx.representation = &rep;
  mutator.begin_loop(ctx);
}

// Empirical mean and covariance of the latent offspring at one fixed z against z and `expected`.
// Standard errors: mean_k ± sqrt(Σ_kk/n); for the sample covariance of Gaussian data
// Var(Ŝ_ij) ≈ (Σ_ii Σ_jj + Σ_ij²)/n. Returns the largest |deviation| / standard error over the
// LD means and LD² covariance entries; callers require < 5 (a false failure has probability
// < 1e-4 over these checks; the draws are seeded anyway).
double max_standard_errors(const qd::Offspring& out, std::size_t first, const RowVector& z,
                           const Eigen::MatrixXd& expected) {
  const auto n = static_cast<Eigen::Index>(out.has_latent.size() - first);
  const Matrix samples = out.latent.bottomRows(n);
  for (std::size_t i = first; i < out.has_latent.size(); ++i) EXPECT_EQ(out.has_latent[i], 1);
  const RowVector mean = samples.colwise().mean();
  const Matrix centred = samples.rowwise() - mean;
  const Eigen::MatrixXd cov = centred.transpose() * centred / static_cast<double>(n - 1);
  const double dn = static_cast<double>(n);
  double worst = 0.0;
  for (Eigen::Index i = 0; i < z.size(); ++i) {
    worst = std::max(worst, std::abs(mean(i) - z(i)) / std::sqrt(expected(i, i) / dn));
    for (Eigen::Index j = 0; j < z.size(); ++j) {
      const double se = std::sqrt((expected(i, i) * expected(j, j) + expected(i, j) * expected(i, j)) / dn);
      worst = std::max(worst, std::abs(cov(i, j) - expected(i, j)) / se);
    }
  }
  return worst;
}

TEST(PomsTest, LatentCovarianceIsSigmaJtJForNonLinearDecoder) {
  const int ld = 3, hidden = 5, p = 7;
  EluModel model(ld, hidden, p);
  // Sanity of the mock itself: closed-form Jacobian against central differences.
  const Matrix z_probe = gaussian(1, ld, 40);
  std::vector<Matrix> jac;
  model.decoder_jacobians(z_probe, jac);
  for (int k = 0; k < ld; ++k) {
    Matrix up = z_probe, down = z_probe, tu, td;
    up(0, k) += 1e-6;
    down(0, k) -= 1e-6;
    model.decode(up, tu);
    model.decode(down, td);
    EXPECT_LT(((tu - td) / 2e-6 - jac[0].col(k).transpose()).cwiseAbs().maxCoeff(), 1e-7);
  }

  const Matrix parent = gaussian(1, p, 41, 2.0);
  Matrix z0;
  model.encode(parent, z0);
  model.decoder_jacobians(z0, jac);
  const Eigen::MatrixXd jtj = jac[0].transpose() * jac[0];
  // Non-trivial: J changes with z (some hidden units sit in the ELU's curved part), and JᵀJ is
  // far from a multiple of the identity.
  std::vector<Matrix> jac_far;
  model.decoder_jacobians(Matrix(z0.array() - 1.0), jac_far);
  EXPECT_GT((jac_far[0] - jac[0]).cwiseAbs().maxCoeff(), 0.01);  // J depends on z (0 for a linear decoder)
  EXPECT_GT(std::abs(jtj(0, 1)), 0.05 * std::sqrt(jtj(0, 0) * jtj(1, 1)));
  qd::testing::Elites archive = archive_with_mean(p, 1.0, 1.0);  // threshold 1 > every parent's error 0

  const double sigma = 0.3;
  const std::size_t n = 20001;  // H = {0}, 20000 latent offspring
  const qd::Parents parents = parents_of(parent.replicate(n, 1), std::vector<double>(n, 0.0));
  for (SigmaMeaning meaning : {SigmaMeaning::kVariance, SigmaMeaning::kStd}) {
    PomsMutator mutator(sigma, meaning, ThresholdMode::kArchiveMean);
    begin(mutator, archive, model);
    EXPECT_DOUBLE_EQ(mutator.threshold(), 1.0);
    const qd::Offspring out = run(mutator, parents, model, 1, 0, archive);
    EXPECT_DOUBLE_EQ(out.metrics.at(1), 1.0 / static_cast<double>(n));
    const double factor = meaning == SigmaMeaning::kVariance ? sigma : sigma * sigma;
    const double other = meaning == SigmaMeaning::kVariance ? sigma * sigma : sigma;
    const double fit = max_standard_errors(out, 1, RowVector(z0.row(0)), factor * jtj);
    EXPECT_LT(fit, 5.0);
    ::testing::Test::RecordProperty(meaning == SigmaMeaning::kVariance ? "max_se_variance" : "max_se_std",
                                    std::to_string(fit));
    // Power check: the other meaning's covariance, and the covariance of isotropic latent noise
    // with the same trace, are both rejected by the same test.
    const double wrong = max_standard_errors(out, 1, RowVector(z0.row(0)), other * jtj);
    EXPECT_GT(wrong, 5.0);
    ::testing::Test::RecordProperty(
        meaning == SigmaMeaning::kVariance ? "max_se_wrong_for_variance" : "max_se_wrong_for_std",
        std::to_string(wrong));
    const Eigen::MatrixXd iso = factor * jtj.trace() / ld * Eigen::MatrixXd::Identity(ld, ld);
    EXPECT_GT(max_standard_errors(out, 1, RowVector(z0.row(0)), iso), 5.0);
  }
  EXPECT_GT(model.vjp_calls, 0);  // the latent step went through decoder_vjp
}

// A linear decoder θ = zA with a square, non-symmetric A (P = LD) that relies on the core's
// default decoder_vjp: the latent step must be Jᵀξ, so its covariance is σJᵀJ, not σJJᵀ (the two
// differ for this A, so a transposed Jacobian fails here).
class SquareLinear final : public qd::Representation {
 public:
  explicit SquareLinear(Matrix a) : a_(std::move(a)) {}
  int latent_size() const noexcept override { return static_cast<int>(a_.rows()); }
  qd::FitReport fit(const qd::Dataset&, const qd::FitContext&) override { return {}; }
  void encode(const Matrix& theta, Matrix& z) const override { z = theta * a_.inverse(); }
  void decode(const Matrix& z, Matrix& theta) const override { theta = z * a_; }
  // ∂θ/∂z: θ_j = Σ_k z_k A_kj, so J = Aᵀ (P × LD).
  void decoder_jacobians(const Matrix& z, std::vector<Matrix>& j) const override {
    j.assign(static_cast<std::size_t>(z.rows()), a_.transpose());
  }
  void save(std::ostream&) const override {}
  void load(std::istream&) override {}

 private:
  Matrix a_;
};

TEST(PomsTest, LatentStepUsesTheTransposedJacobianOfASquareDecoder) {
  Matrix a(3, 3);
  a << 1.0, 2.0, 0.0, 0.0, 1.0, 0.0, 0.5, 0.0, 3.0;
  SquareLinear model(a);
  const Eigen::MatrixXd j = a.transpose();
  const Eigen::MatrixXd jtj = j.transpose() * j, jjt = j * j.transpose();
  ASSERT_GT((jtj - jjt).cwiseAbs().maxCoeff(), 1.0);
  qd::testing::Elites archive = archive_with_mean(3, 1.0, 1.0);
  const std::size_t n = 20001;
  const Matrix parent = gaussian(1, 3, 42);
  Matrix z0;
  model.encode(parent, z0);
  const double sigma = 0.2;
  PomsMutator mutator(sigma, SigmaMeaning::kVariance, ThresholdMode::kArchiveMean);
  begin(mutator, archive, model);
  const qd::Offspring out =
      run(mutator, parents_of(parent.replicate(n, 1), std::vector<double>(n, 0.0)), model, 1, 0, archive);
  EXPECT_LT(max_standard_errors(out, 1, RowVector(z0.row(0)), sigma * jtj), 5.0);
  EXPECT_GT(max_standard_errors(out, 1, RowVector(z0.row(0)), sigma * jjt), 5.0);
}

// The reference threshold is the mean of the stored errors at loop start (not the median, not
// the current model's errors): elites with errors 0.1, 0.2 and 0.9 give 0.4.
TEST(PomsTest, ArchiveMeanThresholdIsTheMeanOfStoredErrors) {
  qd::testing::Elites archive(10, 2, 1);
  archive.add(0, {0, 0}, 0.1).add(4, {0, 0}, 0.2).add(9, {0, 0}, 0.9);
  EluModel model(2, 3, 2);
  PomsMutator mutator(0.1, SigmaMeaning::kVariance, ThresholdMode::kArchiveMean);
  begin(mutator, archive, model);
  EXPECT_DOUBLE_EQ(mutator.threshold(), 0.4);
}

// PoMS-PCA: a linear decoder with orthonormal rows, as PCA's, makes JᵀJ = I.
TEST(PomsTest, PcaLatentCovarianceIsSigmaIdentity) {
  const int ld = 3, p = 8;
  const auto model = qd::testing::LinearModel::random(ld, p, 50);
  const qd::Representation& pca = *model;
  const Matrix parent = gaussian(1, p, 53);
  Matrix z0;
  pca.encode(parent, z0);
  qd::testing::Elites archive = archive_with_mean(p, 1.0, 1.0);
  const std::size_t n = 20001;
  const qd::Parents parents = parents_of(parent.replicate(n, 1), std::vector<double>(n, 0.0));
  const double sigma = 0.1;
  for (SigmaMeaning meaning : {SigmaMeaning::kVariance, SigmaMeaning::kStd}) {
    PomsMutator mutator(sigma, meaning, ThresholdMode::kArchiveMean);
    begin(mutator, archive, pca);
    const qd::Offspring out = run(mutator, parents, pca, 1, 0, archive);
    const double variance = meaning == SigmaMeaning::kVariance ? sigma : sigma * sigma;
    const double fit = max_standard_errors(out, 1, RowVector(z0.row(0)), variance * Eigen::MatrixXd::Identity(ld, ld));
    EXPECT_LT(fit, 5.0);
    ::testing::Test::RecordProperty(meaning == SigmaMeaning::kVariance ? "max_se_variance" : "max_se_std",
                                    std::to_string(fit));
    // An orthonormal linear model reconstructs a latent offspring exactly: θ' = Dec(z') and Enc(θ') = z'.
    Matrix back;
    pca.encode(out.theta.bottomRows(100), back);
    EXPECT_LT((back - out.latent.bottomRows(100)).cwiseAbs().maxCoeff(), 1e-12);
  }
}

// Parents far apart (parent i ≈ 100·i) so every offspring can be traced to its parent.
Matrix distinct_parents(Eigen::Index n, Eigen::Index p) {
  Matrix theta(n, p);
  for (Eigen::Index i = 0; i < n; ++i) theta.row(i) = RowVector::Constant(p, 100.0 * static_cast<double>(i));
  return theta;
}

TEST(PomsTest, SplitFollowsThresholdAndOrder) {
  const int p = 4;
  EluModel model(2, 3, p);
  qd::testing::Elites archive = archive_with_mean(p, 0.1, 0.5);  // mean 0.3
  PomsMutator mutator(1e-8, SigmaMeaning::kStd, ThresholdMode::kArchiveMean);
  begin(mutator, archive, model);
  EXPECT_DOUBLE_EQ(mutator.threshold(), 0.3);

  const Matrix theta = distinct_parents(4, p);
  const qd::Offspring out = run(mutator, parents_of(theta, {0.5, 0.1, 0.9, 0.2}), model, 1, 3, archive);
  ASSERT_EQ(out.metrics.size(), 2u);
  EXPECT_DOUBLE_EQ(out.metrics[0], 0.3);
  EXPECT_DOUBLE_EQ(out.metrics[1], 0.5);  // the mixing ratio
  EXPECT_EQ(mutator.metric_names(), (std::vector<std::string>{"threshold", "mixing_ratio"}));
  EXPECT_EQ(out.has_latent, (std::vector<std::uint8_t>{0, 0, 1, 1}));
  // H = {0, 2} first, in index order, as θ + σε (σ = 1e-8).
  EXPECT_LT((out.theta.row(0) - theta.row(0)).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_LT((out.theta.row(1) - theta.row(2)).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_GT((out.theta.row(0) - theta.row(0)).cwiseAbs().maxCoeff(), 0.0);
  // L = {1, 3}: re-encoded parents (z ≈ Enc θ), decoded; θ' == Dec(z') exactly.
  Matrix z_parents, decoded;
  model.encode(Matrix(theta.row(1)), z_parents);
  EXPECT_LT((out.latent.row(2) - z_parents.row(0)).cwiseAbs().maxCoeff(), 1e-6);
  model.encode(Matrix(theta.row(3)), z_parents);
  EXPECT_LT((out.latent.row(3) - z_parents.row(0)).cwiseAbs().maxCoeff(), 1e-6);
  model.decode(Matrix(out.latent.bottomRows(2)), decoded);
  EXPECT_EQ(Matrix(out.theta.bottomRows(2)), decoded);
  EXPECT_EQ(Matrix(out.latent.topRows(2)), Matrix::Zero(2, 2));
}

TEST(PomsTest, AllBelowThresholdGivesHZeroAllAboveDropsLast) {
  const int p = 4;
  EluModel model(2, 3, p);
  qd::testing::Elites archive = archive_with_mean(p, 0.1, 0.5);  // threshold 0.3
  PomsMutator mutator(1e-8, SigmaMeaning::kVariance, ThresholdMode::kArchiveMean);
  begin(mutator, archive, model);
  const Matrix theta = distinct_parents(4, p);

  EXPECT_EQ(mutator.parameter_space_set(Vector::Constant(4, 0.1)), std::vector<std::size_t>{0});
  const qd::Offspring below = run(mutator, parents_of(theta, {0.1, 0.2, 0.3, 0.0}), model, 1, 0, archive);
  EXPECT_DOUBLE_EQ(below.metrics.at(1), 0.25);
  EXPECT_EQ(below.has_latent, (std::vector<std::uint8_t>{0, 1, 1, 1}));
  EXPECT_LT((below.theta.row(0) - theta.row(0)).cwiseAbs().maxCoeff(), 1e-3);

  EXPECT_EQ(mutator.parameter_space_set(Vector::Constant(4, 0.9)), (std::vector<std::size_t>{0, 1, 2}));
  const qd::Offspring above = run(mutator, parents_of(theta, {0.4, 0.5, 0.6, 0.7}), model, 1, 0, archive);
  EXPECT_DOUBLE_EQ(above.metrics.at(1), 0.75);
  EXPECT_EQ(above.has_latent, (std::vector<std::uint8_t>{0, 0, 0, 1}));
  for (int i = 0; i < 3; ++i) EXPECT_LT((above.theta.row(i) - theta.row(i)).cwiseAbs().maxCoeff(), 1e-3);
  // Ties are not above the threshold (strict >).
  EXPECT_EQ(mutator.parameter_space_set((Vector(3) << 0.3, 0.31, 0.3).finished()), std::vector<std::size_t>{1});
}

TEST(PomsTest, RefreshedThresholdUsesCurrentModelErrors) {
  const int p = 5;
  EluModel model(2, 4, p);
  // Two elites with stale stored errors 0; the refreshed threshold is their current-model mean.
  qd::testing::Elites archive(10, p, 1);
  const Matrix elites = gaussian(2, p, 60);
  for (int i = 0; i < 2; ++i) archive.add(i, std::vector<double>(elites.row(i).data(), elites.row(i).data() + p));
  Vector current;
  model.reconstruction_errors(elites, current);
  PomsMutator refreshed(0.1, SigmaMeaning::kVariance, ThresholdMode::kRefreshed);
  begin(refreshed, archive, model);
  EXPECT_DOUBLE_EQ(refreshed.threshold(), current.mean());
  PomsMutator stale(0.1, SigmaMeaning::kVariance, ThresholdMode::kArchiveMean);
  begin(stale, archive, model);
  EXPECT_EQ(stale.threshold(), 0.0);
  // Refreshed mode splits by current errors: the elite above the mean goes to H even though its
  // stored error says 0.
  const qd::Offspring out = run(refreshed, parents_of(elites, {0.0, 0.0}), model, 1, 0, archive);
  const std::size_t above = current(0) > current(1) ? 0 : 1;
  EXPECT_EQ(refreshed.parameter_space_set(current), std::vector<std::size_t>{above});
  EXPECT_DOUBLE_EQ(out.metrics.at(1), 0.5);
}

TEST(PomsTest, DeterministicPerRngKey) {
  const int p = 6;
  EluModel model(3, 4, p);
  qd::testing::Elites archive = archive_with_mean(p, 0.1, 0.5);
  PomsMutator mutator(0.1, SigmaMeaning::kVariance, ThresholdMode::kArchiveMean);
  begin(mutator, archive, model);
  const qd::Parents parents = parents_of(gaussian(8, p, 70), {0.9, 0.0, 0.5, 0.1, 0.0, 0.7, 0.2, 0.0});
  const qd::Offspring a = run(mutator, parents, model, 2, 5, archive);
  const qd::Offspring b = run(mutator, parents, model, 2, 5, archive);
  const qd::Offspring c = run(mutator, parents, model, 2, 6, archive);
  EXPECT_EQ(a.theta, b.theta);
  EXPECT_EQ(a.latent, b.latent);
  EXPECT_EQ(a.has_latent, b.has_latent);
  EXPECT_EQ(a.has_latent, c.has_latent);  // same split
  EXPECT_GT((a.theta - c.theta).cwiseAbs().minCoeff(), 0.0);

  std::stringstream blob;
  mutator.save(blob);
  PomsMutator restored(0.1, SigmaMeaning::kVariance, ThresholdMode::kArchiveMean);
  restored.load(blob);
  EXPECT_EQ(restored.threshold(), mutator.threshold());
  EXPECT_EQ(run(restored, parents, model, 2, 5, archive).theta, a.theta);
}

TEST(PomsTest, ConfigDefaultsAndRejects) {
  const qd::Config cfg = qd::defaults_of(qd::poms::kPomsParams, "mutator");
  EXPECT_DOUBLE_EQ(cfg.get_float("sigma"), 0.1);
  EXPECT_EQ(cfg.get_string("sigma_meaning"), "variance");
  EXPECT_EQ(cfg.get_string("threshold"), "archive-mean");
  const qd::BuildContext ctx;
  PomsMutator mutator(cfg, ctx);
  EXPECT_TRUE(mutator.needs_latent());
  EXPECT_DOUBLE_EQ(mutator.latent_noise_std(), std::sqrt(0.1));
  qd::Config as_std = cfg;
  as_std.set_string("sigma_meaning", "std", "test");
  EXPECT_DOUBLE_EQ(PomsMutator(as_std, ctx).latent_noise_std(), 0.1);
  EXPECT_THROW(PomsMutator(-1.0, SigmaMeaning::kStd, ThresholdMode::kArchiveMean), qd::ConfigError);
  const qd::Config nj = qd::defaults_of(qd::poms::kNoJacobianParams, "mutator");
  EXPECT_DOUBLE_EQ(nj.get_float("scale"), 1.0);
  EXPECT_TRUE(NoJacobianMutator(nj, ctx).needs_latent());
}

// ---- poms-no-jacobian -------------------------------------------------------------------------

TEST(PomsTest, NoJacobianUsesPopulationStdOfEncodedDataset) {
  const int ld = 3, p = 6;
  EluModel model(ld, 4, p);
  const Matrix data = gaussian(40, p, 80, 1.5);
  qd::Dataset dataset(p);
  for (Eigen::Index i = 0; i < data.rows(); ++i) dataset.add(data.row(i).data(), i, 0);
  qd::testing::Elites archive = archive_with_mean(p, 0.1, 0.5);

  NoJacobianMutator mutator(1.0);
  begin(mutator, archive, model, &dataset);
  Matrix z;
  model.encode(data, z);
  for (int k = 0; k < ld; ++k) {
    const double mean = z.col(k).mean();
    double ss = 0.0;
    for (Eigen::Index i = 0; i < z.rows(); ++i) ss += (z(i, k) - mean) * (z(i, k) - mean);
    EXPECT_NEAR(mutator.latent_std()(k), std::sqrt(ss / 40.0), 1e-12);  // ddof 0
  }

  const qd::Parents parents = parents_of(data.topRows(10), std::vector<double>(10, 5.0));
  const qd::Offspring out = run(mutator, parents, model, 1, 0, archive);
  EXPECT_EQ(out.metrics, std::vector<double>{0.0});  // the mixing ratio
  EXPECT_EQ(out.has_latent, std::vector<std::uint8_t>(10, 1));
  Matrix decoded;
  model.decode(out.latent, decoded);
  EXPECT_EQ(out.theta, decoded);

  // Steps are s ⊙ ε: with the same draws, `scale` 2 doubles every latent step exactly.
  NoJacobianMutator doubled(2.0);
  begin(doubled, archive, model, &dataset);
  const qd::Offspring out2 = run(doubled, parents, model, 1, 0, archive);
  Matrix z_parents;
  model.encode(parents.theta, z_parents);
  EXPECT_LT(((out2.latent - z_parents) - 2.0 * (out.latent - z_parents)).cwiseAbs().maxCoeff(), 1e-12);

  // Determinism and the state blob.
  EXPECT_EQ(run(mutator, parents, model, 1, 0, archive).theta, out.theta);
  EXPECT_GT((run(mutator, parents, model, 1, 1, archive).theta - out.theta).cwiseAbs().minCoeff(), 0.0);
  std::stringstream blob;
  mutator.save(blob);
  NoJacobianMutator restored(1.0);
  restored.load(blob);
  EXPECT_EQ(restored.latent_std(), mutator.latent_std());
}

TEST(PomsTest, NoJacobianStepDistribution) {
  // (z' − Enc θ)/s must be N(0, 1) per coordinate: mean within 5·sqrt(1/n), variance within
  // 5·sqrt(2/n) of 1.
  const int ld = 3, p = 6;
  EluModel model(ld, 4, p);
  const Matrix data = gaussian(40, p, 90, 1.5);
  qd::Dataset dataset(p);
  for (Eigen::Index i = 0; i < data.rows(); ++i) dataset.add(data.row(i).data(), i, 0);
  qd::testing::Elites archive = archive_with_mean(p, 0.1, 0.5);
  NoJacobianMutator mutator(1.0);
  begin(mutator, archive, model, &dataset);
  const std::size_t n = 20000;
  const qd::Parents parents = parents_of(data.topRows(1).replicate(n, 1), std::vector<double>(n, 0.0));
  const qd::Offspring out = run(mutator, parents, model, 1, 0, archive);
  Matrix z0;
  model.encode(Matrix(data.topRows(1)), z0);
  const double dn = static_cast<double>(n);
  for (int k = 0; k < ld; ++k) {
    const Eigen::ArrayXd u = (out.latent.col(k).array() - z0(0, k)) / mutator.latent_std()(k);
    EXPECT_LT(std::abs(u.mean()), 5.0 / std::sqrt(dn));
    EXPECT_LT(std::abs(u.square().mean() - 1.0), 5.0 * std::sqrt(2.0 / dn));
  }
}

// The shipped conformance checks (qd/testing) for both mutators and both thresholds, with the
// non-linear test model as the representation.
TEST(PomsTest, Conforms) {
  const EluModel model(3, 5, 12);
  qd::testing::MutatorCase c;
  c.params = 12;
  c.representation = &model;
  for (const char* threshold : {"archive-mean", "refreshed"}) {
    qd::Config cfg = qd::defaults_of(qd::poms::kPomsParams, "mutator");
    cfg.set_string("threshold", threshold, "test");
    const qd::testing::Report report =
        qd::testing::check_mutator([&] { return std::make_unique<PomsMutator>(cfg, qd::BuildContext{}); }, c);
    EXPECT_TRUE(report.ok()) << threshold << ": " << report;
  }
  const qd::Config cfg = qd::defaults_of(qd::poms::kNoJacobianParams, "mutator");
  const qd::testing::Report report =
      qd::testing::check_mutator([&] { return std::make_unique<NoJacobianMutator>(cfg, qd::BuildContext{}); }, c);
  EXPECT_TRUE(report.ok()) << "poms-no-jacobian: " << report;
}

}  // namespace
