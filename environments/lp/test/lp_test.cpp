// The linear-projection benchmark against its definition (the CMA-ME paper, Sec. 4; pyribs's sphere
// example): fitness and measures at points whose values are known, the grid's cells at its corners,
// and the shipped conformance checks for both environments and the descriptor.
#include "lp.hpp"

#include <qd/errors.hpp>
#include <qd/testing/conformance.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace {

using namespace qd::lp;

qd::Config env_config(int n) {
  qd::Config c = qd::defaults_of(kLpParams, "environment");
  c.set_int("parameters", n);
  return c;
}

// Rolls out rows of `x` (each n values) and returns the traces.
std::vector<qd::Trace> roll(const qd::Environment& env, const std::vector<std::vector<double>>& x) {
  const std::size_t n = x.front().size();
  const qd::PolicyShape shape = qd::PolicyShape::direct(n);
  qd::Matrix params(static_cast<Eigen::Index>(x.size()), static_cast<Eigen::Index>(n));
  for (std::size_t i = 0; i < x.size(); ++i)
    for (std::size_t k = 0; k < n; ++k) params(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(k)) = x[i][k];
  const std::vector<std::uint64_t> seeds(x.size(), 0);
  std::vector<qd::Trace> traces(x.size());
  env.rollout({&shape, params.data(), seeds.data(), 0, x.size()}, traces.data());
  return traces;
}

TEST(Lp, ClipIsIdentityInsideAndReciprocalOutside) {
  EXPECT_EQ(clip(3.0), 3.0);
  EXPECT_EQ(clip(-5.12), -5.12);
  EXPECT_DOUBLE_EQ(clip(10.24), 0.5);
  EXPECT_DOUBLE_EQ(clip(-51.2), -0.1);
}

// The optimum (2.048 everywhere) scores 100, the corner (-5.12 everywhere) 0, for both functions;
// the sphere of x = 0 is 100 * (1 - 2.048^2 / 7.168^2); the Rastrigin of integers off the optimum
// loses exactly the sphere part (cos(2 pi k) = 1).
TEST(Lp, FitnessAtKnownPoints) {
  const int n = 10;
  const LpSphere sphere(env_config(n), {});
  const LpRastrigin rastrigin(env_config(n), {});
  const std::vector<std::vector<double>> x = {std::vector<double>(n, kOptimum), std::vector<double>(n, -kClipBound),
                                              std::vector<double>(n, 0.0), std::vector<double>(n, kOptimum + 1.0)};
  const auto s = roll(sphere, x), r = roll(rastrigin, x);
  EXPECT_DOUBLE_EQ(s[0].fitness, 100.0);
  EXPECT_DOUBLE_EQ(r[0].fitness, 100.0);
  EXPECT_NEAR(s[1].fitness, 0.0, 1e-12);
  EXPECT_NEAR(r[1].fitness, 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(s[2].fitness, 100.0 * (1.0 - (2.048 * 2.048) / (7.168 * 7.168)));
  const double rastrigin_corner = kRastriginA * n + n * (7.168 * 7.168 - kRastriginA * std::cos(2.0 * M_PI * 7.168));
  EXPECT_NEAR(r[3].fitness, 100.0 * (1.0 - n * 1.0 / rastrigin_corner), 1e-9);
  for (const auto& t : s) {
    EXPECT_EQ(t.status, qd::EvalStatus::kOk);
    EXPECT_EQ(t.steps, 1);
  }
}

// Measures: the clipped sums over the first floor(n/2) and the remaining coordinates.
TEST(Lp, MeasuresAreClippedSumsOfEachHalf) {
  const LpSphere sphere(env_config(5), {});
  const auto t = roll(sphere, {{1.0, 2.0, 10.24, -5.12, 20.48}});
  ASSERT_EQ(t[0].main.rows(), 1u);
  EXPECT_DOUBLE_EQ(t[0].main.at(0, 0), 3.0);                // 1 + 2
  EXPECT_DOUBLE_EQ(t[0].main.at(0, 1), 0.5 - 5.12 + 0.25);  // clip(10.24) + (-5.12) + clip(20.48)
  const auto bad = roll(sphere, {{1.0, NAN, 0.0, 0.0, 0.0}});
  EXPECT_EQ(bad[0].status, qd::EvalStatus::kInvalidAction);
}

TEST(Lp, InfoDeclaresAPlainVectorWithFitness) {
  const qd::EnvironmentInfo info = LpRastrigin(env_config(100), {}).info();
  EXPECT_EQ(info.parameters, 100);
  EXPECT_TRUE(info.has_fitness);
  EXPECT_TRUE(std::isnan(info.fitness_lower_bound));
}

// The grid spans +-5.12 n/2 per measure; its corners and centre land where a 100 x 100 grid puts them.
TEST(Lp, MeasuresGridCells) {
  const qd::PolicyShape shape = qd::PolicyShape::direct(100);
  qd::BuildContext ctx;
  ctx.policy = &shape;
  const MeasuresDescriptor d(qd::defaults_of(kMeasuresParams, "descriptor"), ctx);
  const qd::GridSpec g = d.grid();
  EXPECT_EQ(g.cells, 10000);
  EXPECT_EQ(g.lower, (std::vector<double>{-256.0, -256.0}));
  EXPECT_EQ(g.upper, (std::vector<double>{256.0, 256.0}));
  EXPECT_EQ(d.cell_of(-256.0, -256.0), 0);
  EXPECT_EQ(d.cell_of(256.0, 256.0), 9999);
  EXPECT_EQ(d.cell_of(0.0, 0.0), 50 * 100 + 50);
  EXPECT_EQ(d.cell_of(-255.0, 255.0), 0 * 100 + 99);  // measure 0 is the row, measure 1 the column
  EXPECT_EQ(d.cell_of(-1e9, 1e9), 99);                // clipped into the grid

  const qd::PolicyShape network(3, {4}, 2);
  ctx.policy = &network;
  EXPECT_THROW(MeasuresDescriptor(qd::defaults_of(kMeasuresParams, "descriptor"), ctx), qd::InputError);
}

TEST(Lp, EnvironmentsConform) {
  qd::testing::EnvironmentOptions o;
  o.param_scale = 8.0;  // inside and outside the clip bound
  const qd::testing::Report sphere = qd::testing::check_environment(LpSphere(env_config(20), {}), o);
  EXPECT_TRUE(sphere.ok()) << sphere;
  const qd::testing::Report rastrigin = qd::testing::check_environment(LpRastrigin(env_config(20), {}), o);
  EXPECT_TRUE(rastrigin.ok()) << rastrigin;
}

TEST(Lp, DescriptorConforms) {
  const LpSphere env(env_config(20), {});
  const qd::PolicyShape shape = qd::PolicyShape::direct(20);
  qd::BuildContext ctx;
  ctx.policy = &shape;
  const auto traces = qd::testing::rollout_all(env, qd::testing::random_policies(env, 64, {}, 8.0));
  const qd::testing::Report report =
      qd::testing::check_descriptor(MeasuresDescriptor(qd::defaults_of(kMeasuresParams, "descriptor"), ctx), traces);
  EXPECT_TRUE(report.ok()) << report;
}

}  // namespace
