// qd::testing::check_environment against environments whose thread-safety is known: a check that
// fails only sometimes is not a check (issue 32, case 20).
#include <qd/testing/conformance.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <mutex>
#include <string>

namespace {

// A point walking on a line, steered by the policy: observation (position, time), one action.
// `shared`: one Policy for every call, kept between them (a `mutable` member), the mistake the
// check must catch; otherwise one Policy per call.
class Walk final : public qd::Environment {
 public:
  explicit Walk(bool shared) : shared_(shared) {}
  qd::EnvironmentInfo info() const override { return {2, 1, kSteps}; }
  void rollout(const qd::RolloutBatch& batch, qd::Trace* traces) const override {
    std::unique_ptr<qd::Policy> own;
    qd::Policy* policy = nullptr;
    if (shared_) {
      std::call_once(made_, [&] { policy_ = std::make_unique<qd::Policy>(*batch.shape); });
      policy = policy_.get();
    } else {
      own = std::make_unique<qd::Policy>(*batch.shape);
      policy = own.get();
    }
    for (std::size_t i = batch.begin; i < batch.end; ++i) {
      qd::Trace& t = traces[i];
      t.main.reset(1);
      policy->load(batch.row(i));
      double x = 0.0;
      for (int step = 0; step < kSteps; ++step) {
        const float obs[2] = {static_cast<float>(x), static_cast<float>(step) / kSteps};
        const float a = policy->act(obs)[0];
        if (!std::isfinite(a)) {
          t.status = qd::EvalStatus::kInvalidAction;
          t.message = "non-finite action";
          break;
        }
        x += 0.1 * std::tanh(static_cast<double>(a));
        t.main.push(x);
        t.steps = step + 1;
      }
      t.fitness = -std::abs(x);
    }
  }

 private:
  static constexpr int kSteps = 20;
  bool shared_;
  mutable std::once_flag made_;
  mutable std::unique_ptr<qd::Policy> policy_;
};

bool mentions_shared_policy(const qd::testing::Report& r) {
  for (const std::string& f : r.failures())
    if (f.find("loads one qd::Policy object on several threads") != std::string::npos) return true;
  return false;
}

}  // namespace

TEST(Conformance, AnEnvironmentWithAPolicyPerCallConforms) {
  for (int trial = 0; trial < 5; ++trial) {
    const Walk env(false);
    const qd::testing::Report r = qd::testing::check_environment(env);
    EXPECT_TRUE(r.ok()) << r;
  }
}

// Timing decides whether two rollouts overlap; the check must not depend on it: 30 trials, 30
// failures naming the shared Policy (before issue 32, 1 in 30).
TEST(Conformance, APolicySharedBetweenThreadsIsFoundEveryTime) {
  for (int trial = 0; trial < 30; ++trial) {
    const Walk env(true);
    const qd::testing::Report r = qd::testing::check_environment(env);
    EXPECT_TRUE(mentions_shared_policy(r)) << "trial " << trial << ": " << r;
  }
}

TEST(Conformance, OnePolicyLoadedOnOneThreadOnlyIsNotReported) {
  qd::testing::watch_policy_loads(true);
  const qd::PolicyShape shape(1, {2}, 1);
  const std::vector<double> theta(shape.param_count(), 0.5);
  qd::Policy p(shape);
  p.load(theta.data());
  p.load(theta.data());
  std::thread([&] {
    qd::Policy q(shape);
    q.load(theta.data());
  }).join();
  EXPECT_FALSE(qd::testing::policy_loaded_on_two_threads());
  std::thread([&] { p.load(theta.data()); }).join();
  EXPECT_TRUE(qd::testing::policy_loaded_on_two_threads());
  qd::testing::watch_policy_loads(false);
  qd::testing::watch_policy_loads(true);  // a new watch forgets the last one
  EXPECT_FALSE(qd::testing::policy_loaded_on_two_threads());
  qd::testing::watch_policy_loads(false);
}
