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

TEST(Arm, EnvironmentConforms) {
  const qd::testing::Report report = qd::testing::check_environment(environment());
  EXPECT_TRUE(report.ok()) << report;
}

TEST(Arm, DescriptorConforms) {
  const ArmEnvironment env = environment();
  const auto traces = qd::testing::rollout_all(env, qd::testing::random_policies(env, 64));
  const qd::testing::Report report = qd::testing::check_descriptor(descriptor(), traces);
  EXPECT_TRUE(report.ok()) << report;
}

}  // namespace
