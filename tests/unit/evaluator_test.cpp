// The evaluator gives identical results whatever the number of workers.
#include "runtime/evaluator.hpp"
#include "arm.hpp"

#include <qd/rng.hpp>

#include <gtest/gtest.h>

using namespace qd;

TEST(Evaluator, OneAndThreeWorkersGiveIdenticalTracesAndCells) {
  Config ec = defaults_of(arm::kArmParams, "environment");
  arm::ArmEnvironment env(ec, BuildContext{});
  arm::EndpointDescriptor desc(defaults_of(arm::kEndpointParams, "descriptor"), BuildContext{});
  const PolicyShape shape(6, {8, 8}, 3);
  Matrix params(97, static_cast<Eigen::Index>(shape.param_count()));
  Rng rng(11, Stream::kInitial);
  rng.fill_uniform(params.data(), static_cast<std::size_t>(params.size()), -1, 1);
  params(5, 3) = std::nan("");  // a NaN action must give an invalid evaluation, not a crash
  std::vector<std::uint64_t> seeds(97, 0);
  runtime::Evaluator one(env, desc, shape, 1), three(env, desc, shape, 3);
  runtime::Evaluations a, b;
  one.evaluate(params, seeds, a);
  three.evaluate(params, seeds, b);
  ASSERT_EQ(a.cells, b.cells);
  EXPECT_EQ(a.descriptors, b.descriptors);
  for (std::size_t i = 0; i < 97; ++i) {
    EXPECT_EQ(a.traces[i].main.data, b.traces[i].main.data);
    EXPECT_EQ(a.traces[i].fitness, b.traces[i].fitness);
  }
  EXPECT_EQ(a.traces[5].status, EvalStatus::kInvalidAction);
  EXPECT_EQ(a.cells[5], -1);
}

TEST(Evaluator, ArmDescriptorOfAStretchedArm) {
  // All-zero parameters: zero actions, the arm stays stretched along +x, end effector (1, 0).
  arm::ArmEnvironment env(defaults_of(arm::kArmParams, "environment"), BuildContext{});
  arm::EndpointDescriptor desc(defaults_of(arm::kEndpointParams, "descriptor"), BuildContext{});
  const PolicyShape shape(6, {8, 8}, 3);
  Matrix params = Matrix::Zero(1, static_cast<Eigen::Index>(shape.param_count()));
  std::vector<std::uint64_t> seeds(1, 0);
  runtime::Evaluator ev(env, desc, shape, 1);
  runtime::Evaluations out;
  ev.evaluate(params, seeds, out);
  // x = 1 -> bin clipped to 49, y = 0 -> bin 25: cell 25 * 50 + 49.
  EXPECT_EQ(out.cells[0], 25 * 50 + 49);
  EXPECT_EQ(out.traces[0].main.rows(), 6u);  // reset + every 10 of 50 steps
}
