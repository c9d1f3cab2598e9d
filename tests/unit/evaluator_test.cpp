// The evaluator gives identical results whatever the number of workers.
#include "runtime/evaluator.hpp"
#include "arm.hpp"
#include "runtime/process_evaluator.hpp"

#include <qd/rng.hpp>

#include <gtest/gtest.h>

#include <signal.h>

using namespace qd;

namespace {
// Every per-offspring field of two evaluations is identical.
void expect_same(const runtime::Evaluations& a, const runtime::Evaluations& b) {
  EXPECT_EQ(a.cells, b.cells);
  EXPECT_EQ(a.descriptors, b.descriptors);
  EXPECT_EQ(a.fitness, b.fitness);
  EXPECT_EQ(a.steps, b.steps);
  EXPECT_EQ(a.status, b.status);
}

// `rows` policies of `shape` with parameters drawn from U(-1, 1).
Matrix random_params(const PolicyShape& shape, Eigen::Index rows, std::uint64_t seed) {
  Matrix params(rows, static_cast<Eigen::Index>(shape.param_count()));
  Rng rng(seed, Stream::kInitial);
  rng.fill_uniform(params.data(), static_cast<std::size_t>(params.size()), -1, 1);
  return params;
}
}  // namespace

TEST(Evaluator, OneAndThreeWorkersGiveIdenticalTracesAndCells) {
  Config ec = defaults_of(arm::kArmParams, "environment");
  arm::ArmEnvironment env(ec, BuildContext{});
  arm::EndpointDescriptor desc(defaults_of(arm::kEndpointParams, "descriptor"), BuildContext{});
  const PolicyShape shape(6, {8, 8}, 3);
  Matrix params = random_params(shape, 97, 11);
  params(5, 3) = std::nan("");  // a NaN action must give an invalid evaluation, not a crash
  std::vector<std::uint64_t> seeds(97, 0);
  runtime::ThreadEvaluator one(env, desc, shape, 1), three(env, desc, shape, 3);
  runtime::Evaluations a, b;
  one.evaluate(params, seeds, a);
  three.evaluate(params, seeds, b);
  expect_same(a, b);
  EXPECT_EQ(a.status[5], EvalStatus::kInvalidAction);
  EXPECT_EQ(a.cells[5], -1);
}

TEST(Evaluator, ArmDescriptorOfAStretchedArm) {
  // All-zero parameters: zero actions, the arm stays stretched along +x, end effector (1, 0).
  arm::ArmEnvironment env(defaults_of(arm::kArmParams, "environment"), BuildContext{});
  arm::EndpointDescriptor desc(defaults_of(arm::kEndpointParams, "descriptor"), BuildContext{});
  const PolicyShape shape(6, {8, 8}, 3);
  Matrix params = Matrix::Zero(1, static_cast<Eigen::Index>(shape.param_count()));
  std::vector<std::uint64_t> seeds(1, 0);
  runtime::ThreadEvaluator ev(env, desc, shape, 1);
  runtime::Evaluations out;
  ev.evaluate(params, seeds, out);
  // x = 1 -> bin clipped to 49, y = 0 -> bin 25: cell 25 * 50 + 49.
  EXPECT_EQ(out.cells[0], 25 * 50 + 49);
  EXPECT_EQ(out.steps[0], 50);
}

// Worker processes give exactly the thread backend's results, whatever the chunking.
TEST(Evaluator, ProcessesEqualThreads) {
  arm::ArmEnvironment env(defaults_of(arm::kArmParams, "environment"), BuildContext{});
  arm::EndpointDescriptor desc(defaults_of(arm::kEndpointParams, "descriptor"), BuildContext{});
  const PolicyShape shape(6, {8, 8}, 3);
  Matrix params = random_params(shape, 131, 12);
  params(7, 2) = std::nan("");
  std::vector<std::uint64_t> seeds(131, 0);
  runtime::ThreadEvaluator serial(env, desc, shape, 1);
  runtime::ProcessEvaluator procs(env, desc, shape, 3, 131, 60);
  EXPECT_EQ(procs.workers(), 3);
  runtime::Evaluations a, b;
  serial.evaluate(params, seeds, a);
  for (int round = 0; round < 2; ++round) {  // reused shared memory and workers
    procs.evaluate(params, seeds, b);
    expect_same(a, b);
  }
  EXPECT_EQ(b.status[7], EvalStatus::kInvalidAction);
}

// A worker process that dies gives a WorkerFailure naming it, not a hang or a crash.
TEST(Evaluator, DeadWorkerProcessIsReported) {
  arm::ArmEnvironment env(defaults_of(arm::kArmParams, "environment"), BuildContext{});
  arm::EndpointDescriptor desc(defaults_of(arm::kEndpointParams, "descriptor"), BuildContext{});
  const PolicyShape shape(6, {8, 8}, 3);
  Matrix params = Matrix::Zero(16, static_cast<Eigen::Index>(shape.param_count()));
  std::vector<std::uint64_t> seeds(16, 0);
  runtime::ProcessEvaluator procs(env, desc, shape, 2, 16, 60);
  ::kill(procs.worker_pid(1), SIGKILL);
  runtime::Evaluations out;
  try {
    procs.evaluate(params, seeds, out);
    FAIL() << "expected a WorkerFailure";
  } catch (const runtime::WorkerFailure& e) {
    EXPECT_NE(std::string(e.what()).find("worker process 1 (pid"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("signal 9"), std::string::npos) << e.what();
  }
  EXPECT_THROW(procs.evaluate(params, seeds, out), runtime::WorkerFailure);
}
