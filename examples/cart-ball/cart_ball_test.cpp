// The plugin's own test: qd's shipped conformance checks on both components, plus what they promise
// for a policy whose answer is known.
#include "cart_ball.hpp"

#include <qd/testing/conformance.hpp>

#include <gtest/gtest.h>

namespace {

qd::Config defaults() {
  return qd::defaults_of(cart_ball::kCartBallParams, "environment");
}

TEST(CartBall, EnvironmentConforms) {
  const cart_ball::CartBall env(defaults(), qd::BuildContext{});
  const qd::testing::Report report = qd::testing::check_environment(env);
  EXPECT_TRUE(report.ok()) << report;
}

TEST(CartBall, DescriptorConforms) {
  const cart_ball::CartBall env(defaults(), qd::BuildContext{});
  const cart_ball::Landing landing(qd::Config{}, qd::BuildContext{});
  const auto traces = qd::testing::rollout_all(env, qd::testing::random_policies(env, 32));
  const qd::testing::Report report = qd::testing::check_descriptor(landing, traces);
  EXPECT_TRUE(report.ok()) << report;
}

// A policy of zeros leaves the cart still: the ball, dropped at x = 0.2 from y = 0.6, bounces on it
// and never rises above where it started (restitution 0.7), so its fitness is 0.6 and it ends still
// at x = 0.2: direction "still" (1), x bin int((0.2 + 6) / 12 * 24) = 12, height bin int(0.6 / 4 * 8) = 1.
TEST(CartBall, AStillCartGivesTheDropHeightAndTheMiddleCell) {
  const cart_ball::CartBall env(defaults(), qd::BuildContext{});
  qd::testing::PolicyBatch still = qd::testing::random_policies(env, 1);
  still.params.setZero();
  const auto traces = qd::testing::rollout_all(env, still);
  ASSERT_EQ(traces[0].status, qd::EvalStatus::kOk);
  EXPECT_FLOAT_EQ(static_cast<float>(traces[0].fitness), 0.6f);
  const cart_ball::Landing landing(qd::Config{}, qd::BuildContext{});
  std::int64_t cell = -2;
  double values[3] = {};
  landing.describe(traces.data(), 1, &cell, values);
  EXPECT_EQ(cell, (1 * 24 + 12) * 8 + 1);
  EXPECT_EQ(values[0], 1.0);
  EXPECT_NEAR(values[1], 0.2, 1e-3);
  EXPECT_FLOAT_EQ(static_cast<float>(values[2]), 0.6f);
  EXPECT_EQ(landing.grid().labels[0][static_cast<std::size_t>(values[0])], "still");
}

}  // namespace
