// The plugin's own test: qd's shipped conformance checks, plus what this mutator promises.
#include "half_step.hpp"

#include <qd/testing/conformance.hpp>

#include <gtest/gtest.h>

#include <memory>

namespace {

std::unique_ptr<qd::Mutator> make(double step) {
  qd::Config cfg = qd::defaults_of(half_step::kParams, "mutator");
  cfg.set_float("step", step, "test");
  return std::make_unique<half_step::HalfStep>(cfg, qd::BuildContext{});
}

TEST(HalfStep, Conforms) {
  const qd::testing::Report report = qd::testing::check_mutator([] { return make(0.5); });
  EXPECT_TRUE(report.ok()) << report;
}

// step = 1: every offspring is a uniform random point, whatever its parent.
TEST(HalfStep, FullStepForgetsTheParent) {
  qd::Parents parents;
  parents.theta = qd::Matrix::Constant(50, 8, 7.0);
  qd::Rng rng(1, qd::Stream::kMutation);
  qd::MutateContext ctx;  // half-step reads neither the representation nor the archive
  ctx.rng = &rng;
  qd::Offspring out;
  out.reset(50, 8, 0);
  make(1.0)->mutate(parents, 50, ctx, out);
  EXPECT_LE(out.theta.cwiseAbs().maxCoeff(), 1.0);
}

}  // namespace
