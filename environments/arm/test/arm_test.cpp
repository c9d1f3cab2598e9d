// The arm environment and its endpoint descriptor: a known answer and the shipped conformance checks.
#include "arm.hpp"

#include <qd/testing/conformance.hpp>

#include <gtest/gtest.h>

#include <vector>

namespace {

using qd::arm::ArmEnvironment;
using qd::arm::EndpointDescriptor;

ArmEnvironment environment() {
  return ArmEnvironment(qd::defaults_of(qd::arm::kArmParams, "environment"), {});
}
EndpointDescriptor descriptor() {
  return EndpointDescriptor(qd::defaults_of(qd::arm::kEndpointParams, "descriptor"), {});
}

// All-zero parameters: zero actions, the arm stays stretched along +x, end effector (1, 0).
TEST(Arm, StretchedArmEndsInTheLastXBin) {
  const ArmEnvironment env = environment();
  const EndpointDescriptor desc = descriptor();
  const qd::PolicyShape shape(6, {8, 8}, 3);
  const qd::Matrix params = qd::Matrix::Zero(1, static_cast<Eigen::Index>(shape.param_count()));
  const std::uint64_t seed = 0;
  std::vector<qd::Trace> traces(1);
  env.rollout({&shape, params.data(), &seed, 0, 1}, traces.data());
  ASSERT_EQ(traces[0].status, qd::EvalStatus::kOk);
  EXPECT_EQ(traces[0].steps, 50);
  std::int64_t cell = -1;
  double values[2];
  desc.describe(traces.data(), 1, &cell, values);
  // x = 1 -> bin clipped to 49, y = 0 -> bin 25: cell 25 * 50 + 49.
  EXPECT_EQ(cell, 25 * 50 + 49);
  EXPECT_DOUBLE_EQ(values[0], 0.0);  // y
  EXPECT_DOUBLE_EQ(values[1], 1.0);  // x
}

// A policy whose output is the constant action (1, 0, 0): joint 0 turns by dt every step, 50 steps,
// so the final angles are (5, 0, 0). Effort fitness -dt * 50 = -5; angle-variance fitness minus
// the variance of (5, 0, 0), -50/9; the declared bounds are the worst any policy can do.
TEST(Arm, FitnessOfAConstantActionAndTheDeclaredBounds) {
  const qd::PolicyShape shape(6, {8, 8}, 3);
  qd::Matrix params = qd::Matrix::Zero(1, static_cast<Eigen::Index>(shape.param_count()));
  const int last = shape.layers() - 1;
  params(0, static_cast<Eigen::Index>(shape.layer_offset(last) + shape.layer_inputs(last) * 3)) = 1.0;  // bias 0
  const std::uint64_t seed = 0;
  qd::Config variance = qd::defaults_of(qd::arm::kArmParams, "environment");
  variance.set_string("fitness", "angle-variance");
  for (const bool angle : {false, true}) {
    const ArmEnvironment env(angle ? variance : qd::defaults_of(qd::arm::kArmParams, "environment"), {});
    std::vector<qd::Trace> traces(1);
    env.rollout({&shape, params.data(), &seed, 0, 1}, traces.data());
    ASSERT_EQ(traces[0].status, qd::EvalStatus::kOk);
    EXPECT_NEAR(traces[0].aux.last()[0], 5.0, 1e-12);
    EXPECT_NEAR(traces[0].fitness, angle ? -50.0 / 9.0 : -5.0, 1e-12);
    const qd::EnvironmentInfo info = env.info();
    EXPECT_TRUE(info.has_fitness);
    EXPECT_EQ(info.fitness_lower_bound, angle ? -25.0 : -15.0);  // -(dt steps)^2; -dt steps joints
  }
}

TEST(Arm, EnvironmentConforms) {
  const qd::testing::Report report = qd::testing::check_environment(environment());
  EXPECT_TRUE(report.ok()) << report;
}

TEST(Arm, AngleVarianceEnvironmentConforms) {
  qd::Config c = qd::defaults_of(qd::arm::kArmParams, "environment");
  c.set_string("fitness", "angle-variance");
  const qd::testing::Report report = qd::testing::check_environment(ArmEnvironment(c, {}));
  EXPECT_TRUE(report.ok()) << report;
}

TEST(Arm, DescriptorConforms) {
  const ArmEnvironment env = environment();
  const auto traces = qd::testing::rollout_all(env, qd::testing::random_policies(env, 64));
  const qd::testing::Report report = qd::testing::check_descriptor(descriptor(), traces);
  EXPECT_TRUE(report.ok()) << report;
}

}  // namespace
