#include <qd/policy.hpp>

#include <gtest/gtest.h>

#include <cmath>

using qd::Policy;
using qd::PolicyShape;

TEST(Policy, ParameterCountsOfThePaperEnvironments) {
  EXPECT_EQ(PolicyShape(14, {32, 32}, 3).param_count(), 1635u);  // Striker
  EXPECT_EQ(PolicyShape(26, {32, 32}, 4).param_count(), 2052u);  // Walker
  EXPECT_EQ(PolicyShape(30, {32, 32}, 4).param_count(), 2180u);  // Kicker
}

TEST(Policy, LayerOffsetsFollowTheReferenceLayout) {
  const PolicyShape s(14, {32, 32}, 3);
  EXPECT_EQ(s.layer_offset(0), 0u);
  EXPECT_EQ(s.layer_offset(1), 15u * 32u);
  EXPECT_EQ(s.layer_offset(2), 15u * 32u + 33u * 32u);
  EXPECT_EQ(s.layer_offset(3), 1635u);
}

TEST(Policy, HandComputedForwardPass) {
  // Layer 0 is a 3x2 row-major block [w00 w01; w10 w11; b0 b1], layer 1 a 3x1 block [v0; v1; c].
  const PolicyShape s(2, {2}, 1);
  ASSERT_EQ(s.param_count(), 9u);
  const double theta[9] = {1, 2, 3, 4, 0.5, -0.5, 2, -1, 0.25};
  Policy p(s);
  p.load(theta);
  const float obs[2] = {0.1f, 0.2f};
  const float* a = p.act(obs);
  const double h0 = std::tanh(0.1 * 1 + 0.2 * 3 + 0.5);
  const double h1 = std::tanh(0.1 * 2 + 0.2 * 4 - 0.5);
  EXPECT_NEAR(a[0], 2 * h0 - h1 + 0.25, 1e-6);  // float32 inference
}

TEST(Policy, OutputIsLinearNotSquashed) {
  const PolicyShape s(1, {1}, 1);
  // h = tanh(0*x + 0) = 0, y = 0*h + 7: the bias passes through unsquashed.
  const double theta[4] = {0, 0, 0, 7};
  Policy p(s);
  p.load(theta);
  const float obs[1] = {3.0f};
  EXPECT_FLOAT_EQ(p.act(obs)[0], 7.0f);
}
