// Numerical tests of the PCA representation against an independent SVD.
#include "pca.hpp"

#include <qd/dataset.hpp>
#include <qd/errors.hpp>
#include <qd/policy.hpp>
#include <qd/rng.hpp>
#include <qd/testing/conformance.hpp>
#include <qd/testing/training_log.hpp>

#include <gtest/gtest.h>
#include <Eigen/SVD>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace {

using qd::Matrix;
using qd::pca::PcaRepresentation;

Matrix gaussian(Eigen::Index rows, Eigen::Index cols, std::uint64_t key) {
  qd::Rng rng(42, qd::Stream::kPlugin, key);
  Matrix m(rows, cols);
  rng.fill_normal(m.data(), static_cast<std::size_t>(m.size()));
  return m;
}

// Data whose centred version has exactly `rank` directions, with a clear spectral gap.
Matrix low_rank(Eigen::Index n, Eigen::Index p, Eigen::Index rank, std::uint64_t key) {
  Matrix scores = gaussian(n, rank, key);
  for (Eigen::Index k = 0; k < rank; ++k) scores.col(k) *= static_cast<double>(rank - k) * 2.0;
  Matrix data = scores * gaussian(rank, p, key + 1);
  data.rowwise() += gaussian(1, p, key + 2).row(0) * 3.0;
  return data;
}

// Reference answer: JacobiSVD of the centred data (independent of the implementation's
// eigen-decomposition path).
struct Reference {
  Matrix components;       // k × P
  Eigen::VectorXd values;  // singular values
};
Reference reference_svd(const Matrix& data, Eigen::Index k) {
  const Matrix centred = data.rowwise() - data.colwise().mean();
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(Eigen::MatrixXd(centred), Eigen::ComputeThinV);
  return {Matrix(svd.matrixV().leftCols(k).transpose()), svd.singularValues()};
}

// Singular values of W_a W_bᵀ are the cosines of the principal angles between the two subspaces.
Eigen::VectorXd subspace_cosines(const Matrix& a, const Matrix& b) {
  return Eigen::JacobiSVD<Eigen::MatrixXd>(Eigen::MatrixXd(a * b.transpose())).singularValues();
}

void expect_orthonormal_rows(const Matrix& w) {
  const Eigen::MatrixXd gram = w * w.transpose();
  EXPECT_LT((gram - Eigen::MatrixXd::Identity(w.rows(), w.rows())).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(PcaTest, RankLdDataReconstructsToRoundOffAndMatchesSvd) {
  // Both eigen-decomposition paths: N > P (scatter matrix) and N <= P (Gram matrix).
  for (const auto& [n, p] : {std::pair<Eigen::Index, Eigen::Index>{200, 30}, {40, 120}}) {
    const int ld = 5;
    const Matrix data = low_rank(n, p, ld, static_cast<std::uint64_t>(n));
    PcaRepresentation pca(ld, static_cast<std::size_t>(p));
    pca.fit_matrix(data);
    EXPECT_FALSE(pca.tiled());

    Matrix z, rec;
    pca.encode(data, z);
    pca.decode(z, rec);
    EXPECT_LT((data - rec).norm() / data.norm(), 1e-9) << "n=" << n << " p=" << p;
    expect_orthonormal_rows(pca.components());
    EXPECT_LT((pca.mean() - data.colwise().mean()).cwiseAbs().maxCoeff(), 1e-12);

    const Reference ref = reference_svd(data, ld);
    const Eigen::VectorXd cosines = subspace_cosines(pca.components(), ref.components);
    EXPECT_LT((cosines.array() - 1.0).abs().maxCoeff(), 1e-9);
    // Each component individually (the spectrum has gaps): |w_k · v_k| = 1.
    for (int k = 0; k < ld; ++k) EXPECT_NEAR(std::abs(pca.components().row(k).dot(ref.components.row(k))), 1.0, 1e-9);
    const double total = ref.values.squaredNorm();
    for (int k = 0; k < ld; ++k) {
      const double expected = ref.values(k) * ref.values(k) / static_cast<double>(n - 1);
      EXPECT_NEAR(pca.explained_variance()(k), expected, 1e-9 * expected);
      EXPECT_NEAR(pca.explained_variance_ratio()(k), ref.values(k) * ref.values(k) / total, 1e-9);
    }
    EXPECT_NEAR(pca.explained_variance_ratio().sum(), 1.0, 1e-9);  // rank-LD data: all variance kept
  }
}

TEST(PcaTest, FullRankDataTopComponentsMatchSvd) {
  // Noisy data: the top LD subspace and variances must equal the SVD's.
  const Eigen::Index n = 300, p = 25;
  const int ld = 4;
  Matrix data = low_rank(n, p, ld, 7) + 0.05 * gaussian(n, p, 99);
  PcaRepresentation pca(ld, p);
  pca.fit_matrix(data);
  const Reference ref = reference_svd(data, ld);
  EXPECT_LT((subspace_cosines(pca.components(), ref.components).array() - 1.0).abs().maxCoeff(), 1e-9);
  const double total = ref.values.squaredNorm();
  for (int k = 0; k < ld; ++k) {
    const double expected = ref.values(k) * ref.values(k) / static_cast<double>(n - 1);
    EXPECT_NEAR(pca.explained_variance()(k), expected, 1e-9 * expected);
    EXPECT_NEAR(pca.explained_variance_ratio()(k), ref.values(k) * ref.values(k) / total, 1e-12);
  }
}

TEST(PcaTest, SignConventionLargestEntryPositive) {
  const Matrix data = low_rank(60, 12, 3, 3);
  PcaRepresentation a(3, 12), b(3, 12);
  a.fit_matrix(data);
  b.fit_matrix(-data);  // flips every direction's sign in the SVD; the convention undoes it
  for (Eigen::Index r = 0; r < 3; ++r) {
    Eigen::Index arg = 0;
    a.components().row(r).cwiseAbs().maxCoeff(&arg);
    EXPECT_GT(a.components()(r, arg), 0.0);
  }
  EXPECT_LT((a.components() - b.components()).cwiseAbs().maxCoeff(), 1e-10);
}

TEST(PcaTest, TilingRuleWhenFewerSamplesThanComponents) {
  // N = 3 < LD = 5: the reference tiles the data LD times; compare against a literal tiling.
  const Eigen::Index n = 3, p = 10;
  const int ld = 5;
  const Matrix data = gaussian(n, p, 5);
  PcaRepresentation pca(ld, p);
  pca.fit_matrix(data);
  EXPECT_TRUE(pca.tiled());
  expect_orthonormal_rows(pca.components());

  const Matrix tiled = data.replicate(ld, 1);
  const Reference ref = reference_svd(tiled, 2);  // rank of the centred data is N − 1 = 2
  EXPECT_LT((subspace_cosines(pca.components().topRows(2), ref.components).array() - 1.0).abs().maxCoeff(), 1e-9);
  for (int k = 0; k < 2; ++k) {
    const double expected = ref.values(k) * ref.values(k) / static_cast<double>(n * ld - 1);
    EXPECT_NEAR(pca.explained_variance()(k), expected, 1e-9 * expected);
    // Not the un-tiled ddof-1 variance s²/(N − 1):
    const double untiled = ref.values(k) * ref.values(k) / ld / static_cast<double>(n - 1);
    EXPECT_GT(std::abs(pca.explained_variance()(k) - untiled), 1e-3 * untiled);
  }
  for (int k = 2; k < ld; ++k) {
    EXPECT_EQ(pca.explained_variance()(k), 0.0);
    EXPECT_EQ(pca.explained_variance_ratio()(k), 0.0);
  }
  Matrix z, rec;
  pca.encode(data, z);
  pca.decode(z, rec);
  EXPECT_LT((data - rec).norm() / data.norm(), 1e-9);
}

TEST(PcaTest, RefitsFromScratch) {
  const Matrix first = low_rank(50, 10, 4, 11), second = low_rank(80, 10, 4, 21);
  PcaRepresentation warm(4, 10), fresh(4, 10);
  warm.fit_matrix(first);
  warm.fit_matrix(second);
  fresh.fit_matrix(second);
  EXPECT_EQ(warm.components(), fresh.components());
  EXPECT_EQ(warm.mean(), fresh.mean());
  EXPECT_EQ(warm.explained_variance(), fresh.explained_variance());
}

TEST(PcaTest, JacobianAndVjpAreTheConstantTransposedComponents) {
  const Matrix data = low_rank(40, 8, 3, 13);
  PcaRepresentation pca(3, 8);
  pca.fit_matrix(data);
  const Matrix z = gaussian(4, 3, 17), v = gaussian(4, 8, 19);
  std::vector<Matrix> jac;
  pca.decoder_jacobians(z, jac);
  ASSERT_EQ(jac.size(), 4u);
  for (const Matrix& j : jac) EXPECT_EQ(j, Matrix(pca.components().transpose()));
  Matrix out, generic;
  pca.decoder_vjp(z, v, out);
  pca.qd::Representation::decoder_vjp(z, v, generic);  // the core's Jacobian-based default
  EXPECT_LT((out - generic).cwiseAbs().maxCoeff(), 1e-13);
  // Finite differences of the decoder (exact for a linear map up to round-off).
  Matrix base, moved;
  pca.decode(z.topRows(1), base);
  for (int k = 0; k < 3; ++k) {
    Matrix dz = z.topRows(1);
    dz(0, k) += 1e-3;
    pca.decode(dz, moved);
    EXPECT_LT(((moved - base) / 1e-3 - jac[0].col(k).transpose()).cwiseAbs().maxCoeff(), 1e-9);
  }
}

TEST(PcaTest, SaveLoadIsBitExact) {
  const Matrix data = low_rank(30, 9, 4, 23);
  PcaRepresentation a(4, 9), b(4, 9);
  a.fit_matrix(data);
  std::stringstream blob;
  a.save(blob);
  const std::string bytes = blob.str();
  b.load(blob);
  std::stringstream again;
  b.save(again);
  EXPECT_EQ(again.str(), bytes);
  EXPECT_EQ(a.components(), b.components());
  EXPECT_EQ(a.mean(), b.mean());
  Matrix za, zb;
  a.encode(data, za);
  b.encode(data, zb);
  EXPECT_EQ(za, zb);

  PcaRepresentation wrong(3, 9);
  std::stringstream mismatched(bytes);
  EXPECT_THROW(wrong.load(mismatched), qd::StateError);
  std::stringstream truncated(bytes.substr(0, bytes.size() / 2));
  EXPECT_THROW(b.load(truncated), qd::StateError);
}

TEST(PcaTest, LatentLargerThanParameterCountIsConfigError) {
  const qd::PolicyShape shape(2, {3}, 1);  // P = 3·3 + 4·1 = 13
  qd::BuildContext ctx;
  ctx.policy = &shape;
  qd::Config cfg = qd::defaults_of(qd::pca::kParams, "representation");  // latent 50 > 13
  try {
    PcaRepresentation pca(cfg, ctx);
    FAIL() << "expected a ConfigError";
  } catch (const qd::ConfigError& e) {
    EXPECT_EQ(e.key(), "latent");
  }
  cfg.set_int("latent", 13, "test");
  PcaRepresentation ok(cfg, ctx);
  EXPECT_EQ(ok.latent_size(), 13);
}

TEST(PcaTest, FitWritesExplainedVarianceCsv) {
  const Matrix data = low_rank(20, 6, 2, 29);
  qd::Dataset dataset(6);
  for (Eigen::Index i = 0; i < data.rows(); ++i) dataset.add(data.row(i).data(), i, 0);
  PcaRepresentation pca(2, 6);
  qd::testing::MemoryLog log;
  qd::FitContext ctx;
  ctx.log = &log;
  for (int loop = 0; loop < 2; ++loop) {
    ctx.loop = loop;
    const qd::FitReport report = pca.fit(dataset, ctx);
    EXPECT_LT(report.train_loss, 1e-18 * data.squaredNorm() + 1e-20);
  }
  EXPECT_EQ(log.count(), 1u);
  std::istringstream in(log.text("pca.csv"));
  std::string line;
  std::vector<std::string> lines;
  while (std::getline(in, line)) lines.push_back(line);
  ASSERT_EQ(lines.size(), 5u);  // header + 2 loops × 2 components
  EXPECT_EQ(lines[0], "loop,component,explained_variance_ratio");
  EXPECT_EQ(lines[3].rfind("1,0,", 0), 0u);
}

// The shipped conformance checks (qd/testing), built as the core builds it: from its table.
TEST(PcaTest, Conforms) {
  const qd::PolicyShape shape(3, {4}, 2);  // P = 4·4 + 5·2 = 26
  qd::BuildContext ctx;
  ctx.policy = &shape;
  qd::Config cfg = qd::defaults_of(qd::pca::kParams, "representation");
  cfg.set_int("latent", 5, "test");
  const qd::Dataset data = qd::testing::make_dataset(low_rank(30, 26, 8, 31));
  const qd::testing::Report report =
      qd::testing::check_representation([&] { return std::make_unique<PcaRepresentation>(cfg, ctx); }, data);
  EXPECT_TRUE(report.ok()) << report;
}

}  // namespace

// --dry-run's training estimate: one value per loop, equal for equal rows, interpolated between
// the two timed fits.
TEST(PcaEstimate, OneFiniteValuePerLoop) {
  const qd::pca::PcaRepresentation pca(3, 20);
  const std::vector<double> s = pca.estimate_fit_seconds({10, 40, 40, 200});
  ASSERT_EQ(s.size(), 4u);
  for (double v : s) EXPECT_TRUE(std::isfinite(v) && v > 0);
  EXPECT_DOUBLE_EQ(s[1], s[2]);
  EXPECT_TRUE(pca.estimate_fit_seconds({}).empty());
}
