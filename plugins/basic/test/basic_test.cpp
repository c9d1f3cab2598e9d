// Samplers and the iso mutator against their formulas (docs/reference-behaviour.md), and every
// component of the plugin through the shipped conformance checks (qd/testing).
#include "basic.hpp"

#include <qd/testing/conformance.hpp>

#include <gtest/gtest.h>

#include <cmath>

using namespace qd;
using namespace qd::basic;

namespace {
MutateContext context(Rng& rng) {
  MutateContext c;
  c.rng = &rng;
  return c;
}
}  // namespace

TEST(Samplers, GlorotLayerStdsMatchTheReferenceTable) {
  const PolicyShape striker(14, {32, 32}, 3), walker(26, {32, 32}, 4), kicker(30, {32, 32}, 4);
  BuildContext b;
  b.policy = &striker;
  GlorotSampler s(Config("mutator"), b);
  EXPECT_NEAR(s.layer_std(0), 0.1459, 5e-5);
  EXPECT_NEAR(s.layer_std(1), 0.1240, 5e-5);
  EXPECT_NEAR(s.layer_std(2), 0.1667, 5e-5);
  b.policy = &walker;
  GlorotSampler w(Config("mutator"), b);
  EXPECT_NEAR(w.layer_std(0), 0.1302, 5e-5);
  EXPECT_NEAR(w.layer_std(2), 0.1644, 5e-5);
  b.policy = &kicker;
  GlorotSampler k(Config("mutator"), b);
  EXPECT_NEAR(k.layer_std(0), 0.1260, 5e-5);
}

TEST(Samplers, GlorotEmpiricalStdPerLayer) {
  const PolicyShape shape(14, {32, 32}, 3);
  BuildContext b;
  b.policy = &shape;
  GlorotSampler s(Config("mutator"), b);
  Offspring off;
  off.reset(400, shape.param_count(), 0);
  Rng rng(3, Stream::kInitial);
  auto ctx = context(rng);
  s.mutate(Parents{}, 400, ctx, off);
  for (int l = 0; l < 3; ++l) {
    const auto begin = static_cast<Eigen::Index>(shape.layer_offset(l));
    const auto len = static_cast<Eigen::Index>(shape.layer_offset(l + 1)) - begin;
    const Matrix block = off.theta.middleCols(begin, len);
    const double n = static_cast<double>(block.size());
    const double var = block.array().square().sum() / n;
    const double sd = s.layer_std(l);
    EXPECT_NEAR(var, sd * sd, 5 * sd * sd * std::sqrt(2.0 / n)) << "layer " << l;
  }
}

TEST(Samplers, UniformBoundsAndMean) {
  Config c = defaults_of(kUniformParams, "mutator");
  UniformSampler s(c, BuildContext{});
  Offspring off;
  off.reset(100, 500, 0);
  Rng rng(4, Stream::kInitial);
  auto ctx = context(rng);
  s.mutate(Parents{}, 100, ctx, off);
  EXPECT_GE(off.theta.minCoeff(), -1.0);
  EXPECT_LT(off.theta.maxCoeff(), 1.0);
  const double n = static_cast<double>(off.theta.size());
  EXPECT_NEAR(off.theta.mean(), 0.0, 5 * std::sqrt(1.0 / 3.0 / n));
  EXPECT_NEAR(off.theta.array().square().mean(), 1.0 / 3.0, 5 * std::sqrt(4.0 / 45.0 / n));
}

TEST(Samplers, IsoAddsGaussianNoiseOfStdSigma) {
  Config c = defaults_of(kIsoParams, "mutator");
  c.set_float("sigma", 0.3, "test");
  IsoMutator m(c, BuildContext{});
  Parents p;
  p.theta = Matrix::Constant(200, 300, 2.0);
  Offspring off;
  off.reset(200, 300, 0);
  Rng rng(5, Stream::kMutation);
  auto ctx = context(rng);
  m.mutate(p, 200, ctx, off);
  const Matrix d = off.theta - p.theta;
  const double n = static_cast<double>(d.size());
  EXPECT_NEAR(d.mean(), 0.0, 5 * 0.3 / std::sqrt(n));
  EXPECT_NEAR(d.array().square().mean(), 0.09, 5 * 0.09 * std::sqrt(2.0 / n));
  EXPECT_EQ(off.metrics, std::vector<double>{1.0});  // the mixing ratio
}

TEST(NoRepresentation, Conforms) {
  const qd::testing::Report report = qd::testing::check_representation(
      [] { return std::make_unique<NoRepresentation>(Config("representation"), BuildContext{}); },
      qd::testing::make_dataset(qd::testing::random_matrix(10, 7, 3)));
  EXPECT_TRUE(report.ok()) << report;
}

TEST(BasicMutators, Conform) {
  const PolicyShape shape(3, {4}, 2);  // P = 26
  BuildContext with_policy;
  with_policy.policy = &shape;
  qd::testing::MutatorCase c;
  c.params = shape.param_count();
  const std::pair<const char*, qd::testing::MutatorFactory> mutators[] = {
      {"iso", [] { return std::make_unique<IsoMutator>(defaults_of(kIsoParams, "mutator"), BuildContext{}); }},
      {"uniform",
       [] { return std::make_unique<UniformSampler>(defaults_of(kUniformParams, "mutator"), BuildContext{}); }},
      {"glorot", [&] { return std::make_unique<GlorotSampler>(Config("mutator"), with_policy); }},
  };
  for (const auto& [name, make] : mutators) {
    const qd::testing::Report report = qd::testing::check_mutator(make, c);
    EXPECT_TRUE(report.ok()) << name << ": " << report;
  }
}
