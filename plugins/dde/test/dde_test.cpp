// Known-answer tests of the MAPE-DDE mutator (README.md): arm splits, operator order, the
// reconstruction crossover, hand-computed bandit traces and bit-exact save/load.
#include "dde_mutator.hpp"

#include <qd/errors.hpp>
#include <qd/testing/conformance.hpp>
#include <qd/testing/linear_model.hpp>

#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <sstream>
#include <vector>

namespace {

using qd::Matrix;
using qd::Rng;
using qd::Stream;
using qd::dde::DdeMutator;

// A linear "autoencoder": Enc(θ) = (θ − μ) Wᵀ, Dec(z) = z W + μ, with P = 6, LD = 2 and W's rows
// e1 and e2 + e3.
qd::testing::LinearModel linear_model(const qd::RowVector& mu = qd::RowVector::Zero(6)) {
  Matrix w(2, 6);
  w << 1, 0, 0, 0, 0, 0,  //
      0, 1, 1, 0, 0, 0;
  return qd::testing::LinearModel(w, mu);
}

qd::Config base_config() {
  return qd::defaults_of(qd::dde::kDdeParams, "mutator");
}

// An Rng whose first below(9) draw (the iteration-0 arm) is `arm`.
Rng rng_with_first_arm(std::size_t arm, std::uint64_t salt) {
  for (std::uint64_t seed = 0;; ++seed) {
    Rng probe(seed, Stream::kPlugin, salt);
    if (probe.below(qd::dde::kArmCount) == arm) return Rng(seed, Stream::kPlugin, salt);
  }
}

qd::Parents make_parents(std::size_t n) {
  qd::Parents parents;
  parents.theta.resize(static_cast<Eigen::Index>(n), 6);
  for (Eigen::Index i = 0; i < parents.theta.rows(); ++i)
    for (Eigen::Index k = 0; k < 6; ++k) parents.theta(i, k) = 100.0 * static_cast<double>(i) + 0.5 * k - 1.0;
  return parents;
}

TEST(DdeArms, SplitsAreTheReferenceCounts) {
  // (a)/(b)/(c) for a batch of 200: int(f·200) for (a) and (b), the rest to (c).
  const std::array<std::array<std::size_t, 3>, 9> expected200 = {{{0, 0, 200},
                                                                  {50, 0, 150},
                                                                  {100, 0, 100},
                                                                  {150, 0, 50},
                                                                  {200, 0, 0},
                                                                  {0, 50, 150},
                                                                  {0, 100, 100},
                                                                  {0, 150, 50},
                                                                  {0, 200, 0}}};
  // A batch of 7 truncates: int(1.75) = 1, int(3.5) = 3, int(5.25) = 5.
  const std::array<std::array<std::size_t, 3>, 9> expected7 = {
      {{0, 0, 7}, {1, 0, 6}, {3, 0, 4}, {5, 0, 2}, {7, 0, 0}, {0, 1, 6}, {0, 3, 4}, {0, 5, 2}, {0, 7, 0}}};
  for (std::size_t arm = 0; arm < 9; ++arm) {
    const auto s = qd::dde::split_for_arm(arm, 200);
    EXPECT_EQ((std::array<std::size_t, 3>{s.crossover, s.line_dd, s.iso}), expected200[arm]) << "arm " << arm;
    const auto t = qd::dde::split_for_arm(arm, 7);
    EXPECT_EQ((std::array<std::size_t, 3>{t.crossover, t.line_dd, t.iso}), expected7[arm]) << "arm " << arm;
  }
}

// Each arm, forced through the iteration-0 random draw, on 200 distinct parents with all sigmas 0:
// (a) rows are ½(θ + Dec(Enc θ)) with latent Enc(θ), (b) rows are another parent of the (b)
// sub-batch, (c) rows are their own parent, in that order.
TEST(DdeArms, EachArmProducesItsSplitInOrder) {
  qd::Config cfg = base_config();
  cfg.set_float("line_dd_iso_sigma", 0.0, "test");
  cfg.set_float("line_dd_line_sigma", 0.0, "test");
  cfg.set_float("iso_sigma", 0.0, "test");
  const qd::BuildContext bctx;
  qd::RowVector mu(6);
  mu << 0.5, -1, 2, 0, 0, 3;
  const qd::testing::LinearModel rep = linear_model(mu);
  const std::size_t n = 200;
  const qd::Parents parents = make_parents(n);
  Matrix z_all, rec_all;
  rep.encode(parents.theta, z_all);
  rep.decode(z_all, rec_all);

  for (std::size_t arm = 0; arm < 9; ++arm) {
    DdeMutator mutator(cfg, bctx);
    Rng rng = rng_with_first_arm(arm, 1);
    qd::MutateContext mctx;
    mctx.rng = &rng;
    mctx.representation = &rep;
    qd::Offspring out;
    mutator.mutate(parents, n, mctx, out);
    ASSERT_EQ(out.metrics.size(), 2u);
    EXPECT_EQ(out.metrics[0], static_cast<double>(arm));
    EXPECT_EQ(out.metrics.at(1), static_cast<double>(arm) / 9.0);  // the mixing ratio
    ASSERT_EQ(out.theta.rows(), 200);
    ASSERT_EQ(out.latent.rows(), 200);
    const auto s = qd::dde::split_for_arm(arm, n);
    for (std::size_t i = 0; i < n; ++i) {
      const auto r = static_cast<Eigen::Index>(i);
      if (i < s.crossover) {
        ASSERT_EQ(out.has_latent[i], 1) << "arm " << arm << " row " << i;
        for (Eigen::Index k = 0; k < 6; ++k)
          ASSERT_NEAR(out.theta(r, k), 0.5 * (parents.theta(r, k) + rec_all(r, k)), 1e-12);
        ASSERT_EQ(out.latent.row(r), z_all.row(r));
      } else if (i < s.crossover + s.line_dd) {
        ASSERT_EQ(out.has_latent[i], 0);
        const auto partner = static_cast<std::size_t>((out.theta(r, 0) + 1.0) / 100.0 + 0.5);
        ASSERT_NE(partner, i) << "arm " << arm << " row " << i;
        ASSERT_GE(partner, s.crossover);
        ASSERT_LT(partner, s.crossover + s.line_dd);
        ASSERT_EQ(out.theta.row(r), parents.theta.row(static_cast<Eigen::Index>(partner)));
      } else {
        ASSERT_EQ(out.has_latent[i], 0);
        ASSERT_EQ(out.theta.row(r), parents.theta.row(r)) << "arm " << arm << " row " << i;
      }
    }
  }
}

// One literal crossover: W rows e1 and e2 + e3, μ = 0, θ = (1, 2, 4, 3, 0, −2):
// Enc θ = (1, 6), Dec = (1, 6, 6, 0, 0, 0), ½(θ + Dec) = (1, 4, 5, 1.5, 0, −1).
TEST(DdeArms, CrossoverKnownAnswer) {
  const qd::BuildContext bctx;
  const qd::testing::LinearModel rep = linear_model();
  DdeMutator mutator(base_config(), bctx);
  qd::Parents parents;
  parents.theta.resize(4, 6);
  for (Eigen::Index i = 0; i < 4; ++i) parents.theta.row(i) << 1, 2, 4, 3, 0, -2;
  Rng rng = rng_with_first_arm(4, 2);  // arm 4: everything is crossover
  qd::MutateContext mctx;
  mctx.rng = &rng;
  mctx.representation = &rep;
  qd::Offspring out;
  mutator.mutate(parents, 4, mctx, out);
  for (Eigen::Index i = 0; i < 4; ++i) {
    EXPECT_EQ(out.theta.row(i), (qd::RowVector(6) << 1, 4, 5, 1.5, 0, -1).finished());
    EXPECT_EQ(out.latent.row(i), (qd::RowVector(2) << 1, 6).finished());
    EXPECT_EQ(out.has_latent[static_cast<std::size_t>(i)], 1);
  }
}

// ---- The bandit ---------------------------------------------------------------------------------

struct Step {
  int loop;
  int iteration;
  std::size_t added;
  std::size_t replaced;
};

// Two loops, batch 200. Iteration 0 of loop 1 is forced to arm 2, of loop 2 to arm 4.
const std::vector<Step> kScript = {
    {1, 0, 30, 20}, {1, 1, 10, 10}, {1, 2, 0, 0},  {1, 3, 60, 40},  {1, 4, 5, 0},  {2, 0, 50, 50}, {2, 1, 0, 20},
    {2, 2, 100, 0}, {2, 3, 1, 1},   {2, 4, 10, 5}, {2, 5, 120, 30}, {2, 6, 20, 0}, {2, 7, 0, 0},
};

struct Driver {
  qd::testing::LinearModel rep = linear_model();
  qd::Parents parents = make_parents(200);

  // Runs mutate() for step s; returns the arm and leaves the offspring in `out`.
  int mutate(DdeMutator& m, const Step& s, qd::Offspring& out) {
    Rng rng = s.iteration == 0 ? rng_with_first_arm(s.loop == 1 ? 2 : 4, 3)
                               : Rng(5, Stream::kMutation, static_cast<std::uint64_t>(s.loop),
                                     static_cast<std::uint64_t>(s.iteration));
    qd::MutateContext mctx;
    mctx.loop = s.loop;
    mctx.iteration = s.iteration;
    mctx.rng = &rng;
    mctx.representation = &rep;
    if (s.iteration == 0) m.begin_loop(qd::LoopContext{s.loop, nullptr, nullptr, &rep});
    m.mutate(parents, 200, mctx, out);
    return static_cast<int>(out.metrics.at(0));
  }
  static void feedback(DdeMutator& m, const Step& s) {
    qd::Feedback fb;
    fb.loop = s.loop;
    fb.iteration = s.iteration;
    fb.offspring = 200;
    fb.added = s.added;
    fb.replaced = s.replaced;
    fb.rejected = 200 - s.added - s.replaced;
    m.feedback(fb);
  }
};

// Hand computation (reference update, v ← v + (r·e_a − v)/f over all arms, then f_a += 1;
// UCB score v_j + sqrt(2 ln Σf / f_j), first maximum on ties):
//  L1 it0 arm 2 (forced), r = 50/200 = .25  -> v2 = .25, f2 = 2
//  L1 it1: every untried arm scores sqrt(2 ln 10) = 2.146 > .25 + 1.517 -> arm 0, r = .1:
//          v0 = .1, v2 = .25 − .25/2 = .125
//  L1 it2 arm 1 (first untried), r = 0: v0 = .05, v2 = .0625
//  L1 it3 arm 3, r = .5: v0 = .025, v2 = .03125, v3 = .5
//  L1 it4 arm 4, r = .025: v0 = .0125, v2 = .015625, v3 = .25, v4 = .025
//  L2 it0 arm 4 (forced), r = .5: v0 = .00625, v2 = .0078125, v3 = .125, v4 = .2625, f4 = 3
//  L2 it1..it4 arms 5, 6, 7, 8 (untried), r = .1, .5, .01, .075
//  L2 it5: Σf = 19, f = 2 arms have bonus sqrt(ln 19) = 1.7159, arm 4 sqrt(2 ln 19 / 3) = 1.4011;
//          the best v among f = 2 arms is v6 = .125 (score 1.8409) -> arm 6, r = .75: v6 = .4375
//  L2 it6: Σf = 20: arm 6 scores .4375 + sqrt(2 ln 20 / 3) = 1.8507 > arm 8 .0375 + 1.7308 -> arm 6,
//          r = .1: v6 = .4375 + (.1 − .4375)/3 = .325
//  L2 it7: Σf = 21: arm 6 scores .325 + 1.2338 = 1.5588; arm 8 (v8 = .01875) 1.7636 is the best -> arm 8, r = 0
//  Final v (decays of every step applied): see the literal table below.
TEST(DdeBandit, ScriptedTraceReferenceUpdate) {
  const qd::BuildContext bctx;
  DdeMutator m(base_config(), bctx);
  Driver d;
  const std::vector<int> expected_arms = {2, 0, 1, 3, 4, 4, 5, 6, 7, 8, 6, 6, 8};
  std::vector<int> arms;
  qd::Offspring out;
  for (std::size_t k = 0; k < kScript.size(); ++k) {
    arms.push_back(d.mutate(m, kScript[k], out));
    Driver::feedback(m, kScript[k]);
    if (k == 4) {  // end of loop 1
      const std::array<double, 9> v1 = {0.0125, 0.0, 0.015625, 0.25, 0.025, 0.0, 0.0, 0.0, 0.0};
      const std::array<std::int64_t, 9> f1 = {2, 2, 2, 2, 2, 1, 1, 1, 1};
      EXPECT_EQ(m.values(), v1);
      EXPECT_EQ(m.counts(), f1);
    }
  }
  EXPECT_EQ(arms, expected_arms);
  const std::array<double, 9> v = {4.8828125e-05, 0.0,     6.103515625e-05, 0.0009765625, 0.015363511659807958,
                                   0.0015625,     0.24375, 0.000625,        0.009375};
  const std::array<std::int64_t, 9> f = {2, 2, 2, 2, 3, 2, 4, 2, 3};
  for (std::size_t j = 0; j < 9; ++j) EXPECT_DOUBLE_EQ(m.values()[j], v[j]) << "arm " << j;
  EXPECT_EQ(m.counts(), f);
}

// Same script with the standard UCB1 update (f_a += 1; v_a += (r − v_a)/f_a; others untouched):
//  after loop 1: v = (.05, 0, .125, .25, .0125, 0, 0, 0, 0)
//  L2 it0 arm 4: v4 = .0125 + (.5 − .0125)/3 = .175; it1..4 arms 5..8: v = .05, .25, .005, .0375
//  L2 it5: v3 = v6 = .25 with f = 2 tie exactly -> arm 3 (first maximum), r = .75: v3 = 5/12
//  L2 it6: arm 6 (.25 + 1.7349 beats .175 + 1.4166 and the others), r = .1: v6 = .2
//  L2 it7: arm 2 (v2 = .125, f2 = 2 is now the best f = 2 arm), r = 0: v2 = .125·2/3
TEST(DdeBandit, ScriptedTraceUcb1Update) {
  qd::Config cfg = base_config();
  cfg.set_string("update", "ucb1", "test");
  const qd::BuildContext bctx;
  DdeMutator m(cfg, bctx);
  Driver d;
  const std::vector<int> expected_arms = {2, 0, 1, 3, 4, 4, 5, 6, 7, 8, 3, 6, 2};
  std::vector<int> arms;
  qd::Offspring out;
  for (std::size_t k = 0; k < kScript.size(); ++k) {
    arms.push_back(d.mutate(m, kScript[k], out));
    Driver::feedback(m, kScript[k]);
    if (k == 4) {
      const std::array<double, 9> v1 = {0.05, 0.0, 0.125, 0.25, 0.0125, 0.0, 0.0, 0.0, 0.0};
      EXPECT_EQ(m.values(), v1);
    }
  }
  EXPECT_EQ(arms, expected_arms);
  const std::array<double, 9> v = {0.05, 0.0, 0.125 * 2.0 / 3.0, 5.0 / 12.0, 0.175, 0.05, 0.2, 0.005, 0.0375};
  const std::array<std::int64_t, 9> f = {2, 2, 3, 3, 3, 2, 3, 2, 2};
  for (std::size_t j = 0; j < 9; ++j) EXPECT_DOUBLE_EQ(m.values()[j], v[j]) << "arm " << j;
  EXPECT_EQ(m.counts(), f);
}

TEST(DdeBandit, NewCellsRewardAndNoRandomFirstArmOptions) {
  qd::Config cfg = base_config();
  cfg.set_string("reward", "new-cells", "test");
  cfg.set_bool("random_first_arm", false, "test");
  const qd::BuildContext bctx;
  DdeMutator m(cfg, bctx);
  Driver d;
  qd::Offspring out;
  // Without the random first arm, iteration 0 is UCB: all arms tie, so arm 0.
  EXPECT_EQ(d.mutate(m, kScript[0], out), 0);
  Driver::feedback(m, kScript[0]);  // added 30, replaced 20 -> reward 30/200 = .15
  EXPECT_EQ(m.values()[0], 0.15);
}

// Saving at several points (between mutate and feedback too) and continuing in a fresh mutator
// gives the same arms, offspring and bandit state, bit for bit, as never saving.
TEST(DdeBandit, SaveLoadMidSequenceIsBitExact) {
  for (const char* update : {"reference", "ucb1"}) {
    qd::Config cfg = base_config();
    cfg.set_string("update", update, "test");
    const qd::BuildContext bctx;
    Driver d;

    DdeMutator straight(cfg, bctx);
    std::vector<int> arms_straight;
    std::vector<Matrix> offspring_straight;
    qd::Offspring out;
    for (const Step& s : kScript) {
      arms_straight.push_back(d.mutate(straight, s, out));
      offspring_straight.push_back(out.theta);
      Driver::feedback(straight, s);
    }

    for (const std::size_t save_at : {std::size_t{2}, std::size_t{5}, std::size_t{9}}) {
      for (const bool before_feedback : {false, true}) {
        auto current = std::make_unique<DdeMutator>(cfg, bctx);
        std::vector<int> arms;
        for (std::size_t k = 0; k < kScript.size(); ++k) {
          arms.push_back(d.mutate(*current, kScript[k], out));
          ASSERT_EQ(out.theta, offspring_straight[k]) << update << " step " << k;
          auto reload = [&] {
            std::stringstream blob;
            current->save(blob);
            current = std::make_unique<DdeMutator>(cfg, bctx);
            current->load(blob);
          };
          if (k == save_at && before_feedback) reload();
          Driver::feedback(*current, kScript[k]);
          if (k == save_at && !before_feedback) reload();
        }
        EXPECT_EQ(arms, arms_straight) << update;
        EXPECT_EQ(current->values(), straight.values()) << update;  // exact equality of doubles
        EXPECT_EQ(current->counts(), straight.counts()) << update;
        EXPECT_EQ(current->current_arm(), straight.current_arm()) << update;
      }
    }
  }
}

TEST(DdeBandit, LoadRejectsAForeignBlob) {
  const qd::BuildContext bctx;
  DdeMutator m(base_config(), bctx);
  std::stringstream blob("XXXXgarbage");
  EXPECT_THROW(m.load(blob), qd::StateError);
  std::stringstream empty;
  EXPECT_THROW(m.load(empty), qd::StateError);
}

TEST(DdeMutatorInfo, NeedsLatentAndNamesTheArmMetric) {
  const qd::BuildContext bctx;
  DdeMutator m(base_config(), bctx);
  EXPECT_TRUE(m.needs_latent());
  EXPECT_EQ(m.metric_names(), (std::vector<std::string>{"arm", "mixing_ratio"}));
}

// The shipped conformance checks (qd/testing) for both bandit updates, over enough iterations for
// the UCB choice to follow the random first arm (with a random linear model as the representation).
TEST(DdeMutatorInfo, Conforms) {
  for (const char* update : {"reference", "ucb1"}) {
    qd::Config cfg = base_config();
    cfg.set_string("update", update, "test");
    qd::testing::MutatorCase c;
    c.iterations = 5;
    const qd::testing::Report report =
        qd::testing::check_mutator([&] { return std::make_unique<DdeMutator>(cfg, qd::BuildContext{}); }, c);
    EXPECT_TRUE(report.ok()) << update << ": " << report;
  }
}

}  // namespace
