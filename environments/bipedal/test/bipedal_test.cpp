// Known-answer tests for the walker and kicker environments and their descriptors.
#include <gtest/gtest.h>

#include <qd/errors.hpp>
#include <qd/rng.hpp>
#include <qd/testing/conformance.hpp>

#include "bipedal.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace {

using qd::bipedal::EpisodeOptions;
using qd::bipedal::Task;
using qd::bipedal::Termination;

qd::PolicyShape shape_for(Task task) {
  return qd::PolicyShape(qd::bipedal::observation_size(task), {32, 32}, qd::bipedal::kActionSize);
}

std::vector<double> random_params(Task task, std::uint64_t key) {
  const qd::PolicyShape shape = shape_for(task);
  std::vector<double> theta(shape.param_count());
  qd::Rng rng(7, qd::Stream::kPlugin, key);
  rng.fill_uniform(theta.data(), theta.size(), -1.0, 1.0);
  return theta;
}

struct Episode {
  qd::Trace trace;
  std::vector<float> observations;
};

Episode run(const EpisodeOptions& options, const std::vector<double>& theta) {
  qd::bipedal::warm_up_box2d();
  const Task task = options.task;
  qd::Policy policy(shape_for(task));
  policy.load(theta.data());
  Episode e;
  qd::bipedal::run_episode(options, policy, e.trace, &e.observations);
  return e;
}

Episode run(Task task, const std::vector<double>& theta, bool mix_scale = false, int max_steps = 500) {
  EpisodeOptions options;
  options.task = task;
  options.mix_scale = mix_scale;
  options.max_steps = max_steps;
  return run(options, theta);
}

Termination why(const qd::Trace& t) {
  return static_cast<Termination>(t.events.at(0));
}

// ---- Policy shape ------------------------------------------------------------------------------

TEST(BipedalPolicy, ParamCounts) {
  EXPECT_EQ(qd::PolicyShape(26, {32, 32}, 4).param_count(), 2052u);
  EXPECT_EQ(qd::PolicyShape(30, {32, 32}, 4).param_count(), 2180u);
}

// ---- Terrain (the reference's heights, structural facts) -----------------------------------------

TEST(BipedalTerrain, StructuralFacts) {
  const auto& h = qd::bipedal::walker_terrain_heights();
  ASSERT_EQ(h.size(), 200u);
  for (int i = 0; i <= 20; ++i) EXPECT_NEAR(h[i], 3.333333, 1e-6) << i;
  EXPECT_NEAR(*std::min_element(h.begin(), h.end()), 2.963666, 5e-7);
  EXPECT_NEAR(*std::max_element(h.begin(), h.end()), 3.595202, 5e-7);
  EXPECT_NEAR(h[100], 3.423785, 5e-7);
  // A point right after a counter reset repeats the previous height; no other point does.
  const int resets[] = {19,  26,  32,  37,  44,  51,  60,  68,  76,  82,  89,  95,  104,
                        113, 118, 124, 130, 137, 145, 152, 160, 167, 175, 183, 189, 196};
  std::set<int> repeats;
  for (int r : resets) repeats.insert(r + 1);
  for (int i = 21; i < 200; ++i) EXPECT_EQ(h[i] == h[i - 1], repeats.count(i) == 1) << "i = " << i;
}

TEST(BipedalTerrain, FullPrecisionHeights) {
  // gym 0.11 keeps the heights as Python floats (doubles) and Box2D rounds each to float32. The
  // values below were recomputed from gym 0.11's algorithm and seeding (numpy legacy MT19937 seeded
  // with [4147133540, 85405754]); a table rounded to 6 decimals moves 135 of the 200 float32
  // points by a few ulps.
  const auto& h = qd::bipedal::walker_terrain_heights();
  EXPECT_EQ(h[0], 400.0 / 30.0 / 4.0);
  EXPECT_EQ(h[21], 3.3491985708930807);
  EXPECT_EQ(h[100], 3.42378544753831);
  EXPECT_EQ(h[177], 2.9636658252286603);
  EXPECT_EQ(h[199], 3.431130367014732);
  EXPECT_EQ(static_cast<float>(h[21]), 3.3491985708930807f);
}

// ---- First observation -------------------------------------------------------------------------

TEST(BipedalWalker, FirstObservationAfterResetStep) {
  const Episode e = run(Task::kWalker, std::vector<double>(2052, 0.0));
  ASSERT_GE(e.observations.size(), 26u);
  const float* obs = e.observations.data();
  // obs[24..25] is the hull position after the reset step, the same state as the first row.
  EXPECT_EQ(obs[24], static_cast<float>(e.trace.main.at(0, 0)));
  EXPECT_EQ(obs[25], static_cast<float>(e.trace.main.at(0, 1)));
  EXPECT_NEAR(obs[24], 46.6667, 0.01);
  EXPECT_NEAR(obs[25], 5.6, 0.1);
  // One step of free fall of the hull: vy = -g dt = -0.2, obs[3] = 0.08 vy.
  EXPECT_NEAR(obs[3], -0.016, 1e-3);
  for (int i = 14; i < 24; ++i) {
    EXPECT_GT(obs[i], 0.0f);
    EXPECT_LE(obs[i], 1.0f);
  }
  // The vertical ray (i = 0) hits the terrain below the hull: (y - terrain(x)) / LIDAR_RANGE.
  const auto& h = qd::bipedal::walker_terrain_heights();
  const double s = obs[24] / qd::bipedal::kTerrainStep - 99.0;  // between points 99 and 100
  const double ground = h[99] + s * (h[100] - h[99]);
  EXPECT_NEAR(obs[14], (obs[25] - ground) / (160.0 / 30.0), 1e-4);
  EXPECT_TRUE(obs[8] == 0.0f || obs[8] == 1.0f);
  EXPECT_TRUE(obs[13] == 0.0f || obs[13] == 1.0f);
}

TEST(BipedalKicker, FirstObservationAfterResetStep) {
  const Episode e = run(Task::kKicker, std::vector<double>(2180, 0.0));
  ASSERT_GE(e.observations.size(), 30u);
  const float* obs = e.observations.data();
  // The ball starts at (46.6667, 4.0) and falls for one step with linear damping 1:
  // vy = -g dt / (1 + dt), y = 4 + vy dt.
  const double vy = -10.0 * 0.02 / (1.0 + 0.02);
  EXPECT_NEAR(obs[26], 140.0 / 3.0, 1e-5);
  EXPECT_NEAR(obs[27], 4.0 + vy * 0.02, 1e-5);
  EXPECT_NEAR(obs[28], 0.0, 1e-6);
  EXPECT_NEAR(obs[29], vy, 1e-5);
  EXPECT_NEAR(obs[24], 44.3333, 0.01);
  for (int i = 14; i < 24; ++i) {
    EXPECT_GT(obs[i], 0.0f);
    EXPECT_LE(obs[i], 1.0f);
  }
  EXPECT_NEAR(obs[14], (obs[25] - 10.0 / 3.0) / (160.0 / 30.0), 1e-5);  // flat ground, ball invisible
  EXPECT_TRUE(obs[8] == 0.0f || obs[8] == 1.0f);
  EXPECT_TRUE(obs[13] == 0.0f || obs[13] == 1.0f);
  // The trace's first row is the ball at reset (after the reset step), not after step 0.
  EXPECT_EQ(static_cast<float>(e.trace.main.at(0, 0)), obs[26]);
  EXPECT_EQ(static_cast<float>(e.trace.main.at(0, 1)), obs[27]);
}

// ---- Kicker episodes ----------------------------------------------------------------------------

TEST(BipedalKicker, ZeroPolicyEndsInCellZero) {
  const Episode e = run(Task::kKicker, std::vector<double>(2180, 0.0));
  EXPECT_EQ(e.trace.status, qd::EvalStatus::kOk);
  EXPECT_LT(e.trace.steps, 500);
  EXPECT_NE(why(e.trace), Termination::kMaxSteps);
  EXPECT_EQ(why(e.trace), Termination::kAllStill);  // limp robot resting on its legs, ball not moved
  double values[2];
  EXPECT_EQ(qd::bipedal::kicker_ball_cell(e.trace, values), 0);
  EXPECT_LT(values[0], 4.0);
  EXPECT_LE(values[1], 46.667);
}

TEST(BipedalKicker, ActionIsCutOffAfter101Calls) {
  // A policy (found by search, fixed seed) whose episode lasts past step 120.
  const Episode e = run(Task::kKicker, random_params(Task::kKicker, 4));
  ASSERT_EQ(e.trace.status, qd::EvalStatus::kOk);
  ASSERT_GT(e.trace.steps, 120);
  // Rows: reset, steps 0, 20, ..., 100 (row 6), 120 (row 7). Columns 8..11 are the applied action.
  const auto applied = [&](std::size_t row) {
    double s = 0.0;
    for (int c = 8; c < 12; ++c) s += std::fabs(e.trace.aux.at(row, c));
    return s;
  };
  EXPECT_EQ(applied(0), 0.0);
  EXPECT_GT(applied(6), 0.0);  // step 100 = the 101st call: still controlled
  EXPECT_EQ(applied(7), 0.0);  // step 120: limp
}

TEST(BipedalKicker, NonFiniteActionIsInvalid) {
  std::vector<double> theta(2180, 0.0);
  const qd::PolicyShape shape = shape_for(Task::kKicker);
  theta[shape.layer_offset(2) + 32 * 4 + 1] = std::nan("");  // output bias of action 1
  const Episode e = run(Task::kKicker, theta);
  EXPECT_EQ(e.trace.status, qd::EvalStatus::kInvalidAction);
  EXPECT_EQ(e.trace.steps, 0);
}

// ---- Walker termination and truncation ------------------------------------------------------------

TEST(BipedalWalker, LimpRobotFallsOnItsHull) {
  // Zero parameters: zero torque, the robot folds and the hull touches the ground.
  const Episode e = run(Task::kWalker, std::vector<double>(2052, 0.0));
  EXPECT_EQ(e.trace.status, qd::EvalStatus::kOk);
  EXPECT_EQ(why(e.trace), Termination::kHullContact);
  EXPECT_LT(e.trace.steps, 500);
  EXPECT_LE(e.trace.main.rows(), 25u);
  // Rows: reset, every 20th step, and the done step.
  const std::size_t expected =
      1 + static_cast<std::size_t>((e.trace.steps - 1) / 20 + 1) + ((e.trace.steps - 1) % 20 == 0 ? 0 : 1);
  EXPECT_EQ(e.trace.main.rows(), expected);
  EXPECT_EQ(e.trace.aux.rows(), expected);
  EXPECT_LT(e.trace.main.last()[1], 5.0);  // the hull came down
}

TEST(BipedalWalker, RowsAreTruncatedToMaxStepsOver20) {
  // Same limp robot, cut at 100 steps (it falls later): rows reset, 0, 20, 40, 60, 80 -> first 5 kept.
  const Episode full = run(Task::kWalker, std::vector<double>(2052, 0.0));
  ASSERT_GT(full.trace.steps, 100);
  const Episode e = run(Task::kWalker, std::vector<double>(2052, 0.0), false, 100);
  EXPECT_EQ(e.trace.steps, 100);
  EXPECT_EQ(why(e.trace), Termination::kMaxSteps);
  ASSERT_EQ(e.trace.main.rows(), 5u);
  for (std::size_t i = 0; i < e.trace.main.data.size(); ++i) EXPECT_EQ(e.trace.main.data[i], full.trace.main.data[i]);
}

TEST(BipedalWalker, StillHullEndsTheEpisode) {
  // A fixed random policy (found by search) whose robot stands still until Box2D puts it to sleep.
  const Episode e = run(Task::kWalker, random_params(Task::kWalker, 5));
  ASSERT_EQ(why(e.trace), Termination::kHullStill);
  ASSERT_LT(e.trace.steps, 460);  // the done row is kept
  const double* last = e.trace.aux.last();
  EXPECT_LE(std::hypot(last[3], last[4]), 0.0005);
  EXPECT_EQ(e.trace.main.rows(), e.trace.aux.rows());
}

TEST(BipedalWalker, EpisodesStayWithinLimits) {
  for (std::uint64_t key = 1; key <= 6; ++key) {
    const Episode e = run(Task::kWalker, random_params(Task::kWalker, key));
    EXPECT_EQ(e.trace.status, qd::EvalStatus::kOk);
    EXPECT_LE(e.trace.steps, 500);
    EXPECT_GE(e.trace.main.rows(), 1u);
    EXPECT_LE(e.trace.main.rows(), 25u);
    EXPECT_EQ(e.trace.main.cols, 3);
    EXPECT_EQ(e.trace.aux.cols, 5);
    EXPECT_EQ(e.observations.size(), static_cast<std::size_t>(e.trace.steps) * 26u);
  }
}

// ---- mix_scale -----------------------------------------------------------------------------------

// A random policy that ignores the inputs [first, last], so that a variant that changes only those
// follows the plain environment's trajectory.
std::vector<double> policy_ignoring(Task task, int first, int last, std::uint64_t key = 11) {
  std::vector<double> theta = random_params(task, key);
  for (int r = first; r <= last; ++r)
    for (int c = 0; c < 32; ++c) theta[static_cast<std::size_t>(r) * 32 + static_cast<std::size_t>(c)] = 0.0;
  return theta;
}

// With mix_scale and `elements`, exactly the entries [first, last] are 100 x the plain environment's.
void check_mix_scale(Task task, qd::bipedal::MixScaleElements elements, int first, int last) {
  const std::vector<double> theta = policy_ignoring(task, first, last);
  EpisodeOptions options;
  options.task = task;
  const Episode plain = run(options, theta);
  options.mix_scale = true;
  options.mix_scale_elements = elements;
  const Episode mixed = run(options, theta);
  ASSERT_GT(plain.trace.steps, 5);
  ASSERT_EQ(plain.observations.size(), mixed.observations.size());
  const int n = qd::bipedal::observation_size(task);
  for (std::size_t k = 0; k < plain.observations.size(); ++k) {
    const int i = static_cast<int>(k % static_cast<std::size_t>(n));
    const float expected = (i >= first && i <= last)
                               ? static_cast<float>(100.0 * static_cast<double>(plain.observations[k]))
                               : plain.observations[k];
    ASSERT_EQ(mixed.observations[k], expected) << "step " << k / n << " entry " << i;
  }
  EXPECT_EQ(plain.trace.main.data, mixed.trace.main.data);
  const auto range = qd::bipedal::mix_scaled_range(task, elements);
  EXPECT_EQ(range.first, first <= last ? first : range.second);
  EXPECT_EQ(range.second, first <= last ? last + 1 : range.first);
}

TEST(BipedalWalker, MixScaleCompanionMultipliesLidarAndPosition) {
  check_mix_scale(Task::kWalker, qd::bipedal::MixScaleElements::kCompanion, 14, 25);
}
TEST(BipedalWalker, MixScalePaperMultipliesHullPositionOnly) {
  check_mix_scale(Task::kWalker, qd::bipedal::MixScaleElements::kPaper, 24, 25);
}
TEST(BipedalKicker, MixScaleCompanionMultipliesLidarPositionsAndBall) {
  check_mix_scale(Task::kKicker, qd::bipedal::MixScaleElements::kCompanion, 14, 29);
}
TEST(BipedalKicker, MixScalePaperIsTheUnscaledOriginal) {
  check_mix_scale(Task::kKicker, qd::bipedal::MixScaleElements::kPaper, 1, 0);  // no entry scaled
}

TEST(BipedalKicker, NormalisedDividesHullAndBallPositionsOnly) {
  // The first of these random policies that moves the ball, so that its entries vary.
  EpisodeOptions options;
  options.task = Task::kKicker;
  std::vector<double> theta;
  Episode plain;
  for (std::uint64_t key = 1; key < 64 && theta.empty(); ++key) {
    std::vector<double> candidate = policy_ignoring(Task::kKicker, 24, 27, key);
    plain = run(options, candidate);
    for (std::size_t k = 26; k < plain.observations.size(); k += 30)
      if (std::fabs(plain.observations[k] - 46.6667) > 0.5) theta = candidate;
  }
  ASSERT_FALSE(theta.empty()) << "no policy among the first 63 moves the ball";
  options.normalised = true;
  const Episode norm = run(options, theta);
  ASSERT_GT(plain.trace.steps, 5);
  ASSERT_EQ(plain.observations.size(), norm.observations.size());
  EXPECT_EQ(plain.trace.main.data, norm.trace.main.data);
  for (std::size_t k = 0; k < plain.observations.size(); ++k) {
    const int i = static_cast<int>(k % 30u);
    const double v = plain.observations[k];
    double expected = v;
    if (i == 24 || i == 26) expected = v / (14.0 / 30.0 * 200.0);
    if (i == 25 || i == 27) expected = (v - 4.0) / 3.0;
    ASSERT_NEAR(norm.observations[k], expected, 1e-6 * std::max(1.0, std::fabs(expected)))
        << "step " << k / 30 << " entry " << i;
  }
  EXPECT_NEAR(norm.observations[24], 44.3333 / 93.3333, 1e-4);  // hull start x = 44.333
  EXPECT_NEAR(norm.observations[26], 0.5, 1e-6);                // ball start x = 46.667
}

TEST(BipedalEnvironment, ObservationOptions) {
  qd::Config walker = qd::defaults_of(qd::bipedal::kWalkerParams, "environment");
  EXPECT_EQ(qd::bipedal::WalkerEnvironment(walker, {}).options().mix_scale_elements,
            qd::bipedal::MixScaleElements::kCompanion);
  walker.set_string("mix_scale_elements", "paper");
  EXPECT_EQ(qd::bipedal::WalkerEnvironment(walker, {}).options().mix_scale_elements,
            qd::bipedal::MixScaleElements::kPaper);
  EXPECT_FALSE(qd::bipedal::WalkerEnvironment(walker, {}).options().normalised);

  qd::Config kicker = qd::defaults_of(qd::bipedal::kKickerParams, "environment");
  EXPECT_FALSE(qd::bipedal::KickerEnvironment(kicker, {}).options().normalised);
  kicker.set_bool("normalised", true);
  EXPECT_TRUE(qd::bipedal::KickerEnvironment(kicker, {}).options().normalised);
  kicker.set_bool("mix_scale", true);
  EXPECT_THROW(qd::bipedal::KickerEnvironment(kicker, {}), qd::ConfigError);
}

// ---- Descriptors on synthetic traces -------------------------------------------------------------

qd::Trace walker_trace(double mean_y, double final_x, int rows, int left_contacts, int right_contacts) {
  qd::Trace t;
  t.main.reset(3);
  t.aux.reset(5);
  for (int r = 0; r < rows; ++r) {
    t.main.push(r + 1 == rows ? final_x : 46.0, mean_y, 0.0);
    t.aux.push(r < left_contacts ? 1.0 : 0.0, r < right_contacts ? 1.0 : 0.0, 0.0, 0.0, 0.0);
  }
  return t;
}

std::int64_t walker_cell(const qd::Trace& t, bool corrected) {
  double v[4];
  return qd::bipedal::walker_gait_cell(t, corrected, v);
}

TEST(BipedalWalkerGait, ReferenceVersusCorrectedContactBins) {
  // mean y 5.0 -> d0 = int(0.5 / 1.7 * 5) = 1; x = 50 -> d1 = int(53.57) = 53; left 11/20 = 0.55.
  const qd::Trace t = walker_trace(5.0, 50.0, 20, 11, 0);
  EXPECT_EQ(walker_cell(t, false), 1 * 2500 + 53 * 25 + 5 * 5 + 0);  // d2 = int(5.5) = 5
  EXPECT_EQ(walker_cell(t, true), 1 * 2500 + 53 * 25 + 2 * 5 + 0);   // d2 = int(2.75) = 2
  double v[4];
  qd::bipedal::walker_gait_cell(t, false, v);
  EXPECT_DOUBLE_EQ(v[0], 5.0);
  EXPECT_DOUBLE_EQ(v[1], 50.0 / (14.0 / 30.0 * 200.0));
  EXPECT_DOUBLE_EQ(v[2], 0.55);
  EXPECT_DOUBLE_EQ(v[3], 0.0);
}

TEST(BipedalWalkerGait, ReferenceCellsCollide) {
  // (d1, d2, d3) = (53, 5, 0) and (54, 0, 0) share a cell in reference mode only.
  const qd::Trace a = walker_trace(5.0, 50.0, 20, 11, 0);
  const qd::Trace b = walker_trace(5.0, 54.5 / 100.0 * 93.3333333, 20, 0, 0);
  EXPECT_EQ(walker_cell(a, false), walker_cell(b, false));
  EXPECT_NE(walker_cell(a, true), walker_cell(b, true));
}

TEST(BipedalWalkerGait, BinEdges) {
  // d0: y clipped to [4.5, 6.2].
  EXPECT_EQ(walker_cell(walker_trace(4.0, 0.0, 5, 0, 0), true), 0);
  EXPECT_EQ(walker_cell(walker_trace(4.5, 0.0, 5, 0, 0), true), 0);
  EXPECT_EQ(walker_cell(walker_trace(6.2, 0.0, 5, 0, 0), true), 4 * 2500);
  EXPECT_EQ(walker_cell(walker_trace(9.0, 0.0, 5, 0, 0), true), 4 * 2500);
  // d1: x / 93.333, 100 bins, clipped.
  EXPECT_EQ(walker_cell(walker_trace(4.5, -3.0, 5, 0, 0), true), 0);
  EXPECT_EQ(walker_cell(walker_trace(4.5, 46.6667, 5, 0, 0), true), 50 * 25);  // start x in bin 50
  EXPECT_EQ(walker_cell(walker_trace(4.5, 93.0, 5, 0, 0), true), 99 * 25);
  EXPECT_EQ(walker_cell(walker_trace(4.5, 200.0, 5, 0, 0), true), 99 * 25);
  // Contacts over 5 rows: 1/5 = 0.2 -> reference int(2.0) = 2, corrected int(1.0) = 1.
  EXPECT_EQ(walker_cell(walker_trace(4.5, 0.0, 5, 1, 0), false), 2 * 5);
  EXPECT_EQ(walker_cell(walker_trace(4.5, 0.0, 5, 1, 0), true), 1 * 5);
  EXPECT_EQ(walker_cell(walker_trace(4.5, 0.0, 5, 0, 5), false), 9);  // mean 1 -> clip to 9
  EXPECT_EQ(walker_cell(walker_trace(4.5, 0.0, 5, 0, 5), true), 4);
}

TEST(BipedalWalkerGait, OutOfRangeIndexIsMinusOne) {
  // d0 = 4, d1 = 99, d2 = d3 = 9: 10000 + 2475 + 45 + 9 = 12529 >= 12500.
  const qd::Trace t = walker_trace(6.2, 93.0, 5, 5, 5);
  EXPECT_EQ(walker_cell(t, false), -1);
  EXPECT_EQ(walker_cell(t, true), 12499);
  EXPECT_EQ(walker_cell(qd::Trace{}, false), -1);

  qd::Config cfg = qd::defaults_of(qd::bipedal::kWalkerGaitParams, "descriptor");
  const qd::bipedal::WalkerGaitDescriptor reference(cfg, qd::BuildContext{});
  EXPECT_EQ(reference.grid().cells, 12500);
  const qd::Trace batch[2] = {t, walker_trace(5.0, 50.0, 20, 11, 0)};
  std::int64_t cells[2];
  double values[8];
  reference.describe(batch, 2, cells, values);
  EXPECT_EQ(cells[0], -1);
  EXPECT_EQ(cells[1], 3850);
  cfg.set_string("contact_bins", "corrected", "test");
  const qd::bipedal::WalkerGaitDescriptor corrected(cfg, qd::BuildContext{});
  corrected.describe(batch, 2, cells, values);
  EXPECT_EQ(cells[0], 12499);
  EXPECT_EQ(cells[1], 3835);
}

qd::Trace kicker_trace(double max_y, double final_x) {
  qd::Trace t;
  t.main.reset(2);
  t.main.push(46.6667, 3.9);
  t.main.push(46.0, max_y);
  t.main.push(final_x, 3.667);
  return t;
}

std::int64_t kicker_cell(const qd::Trace& t) {
  double v[2];
  return qd::bipedal::kicker_ball_cell(t, v);
}

TEST(BipedalKickerBall, BinEdges) {
  const double x0 = 140.0 / 3.0;
  EXPECT_EQ(kicker_cell(kicker_trace(3.0, 40.0)), 0);       // below both ranges
  EXPECT_EQ(kicker_cell(kicker_trace(4.09, x0)), 1 * 200);  // 0.09 / 0.06 = 1.5
  EXPECT_EQ(kicker_cell(kicker_trace(6.99, x0)), 49 * 200);
  EXPECT_EQ(kicker_cell(kicker_trace(7.0, x0)), 49 * 200);  // top edge clipped into the last bin
  EXPECT_EQ(kicker_cell(kicker_trace(10.0, x0)), 49 * 200);
  EXPECT_EQ(kicker_cell(kicker_trace(3.0, x0 + 0.15)), 1);  // 0.1-unit bins
  EXPECT_EQ(kicker_cell(kicker_trace(3.0, x0 + 10.05)), 100);
  EXPECT_EQ(kicker_cell(kicker_trace(3.0, x0 + 19.95)), 199);
  EXPECT_EQ(kicker_cell(kicker_trace(3.0, x0 + 20.0)), 199);
  EXPECT_EQ(kicker_cell(kicker_trace(3.0, 90.0)), 199);
  EXPECT_EQ(kicker_cell(kicker_trace(5.5, x0 + 5.05)), 25 * 200 + 50);
  EXPECT_EQ(kicker_cell(qd::Trace{}), -1);
  double v[2];
  qd::bipedal::kicker_ball_cell(kicker_trace(5.5, 50.0), v);
  EXPECT_DOUBLE_EQ(v[0], 5.5);
  EXPECT_DOUBLE_EQ(v[1], 50.0);
}

// ---- Environment component: determinism and threads -----------------------------------------------

void check_determinism(Task task) {
  const qd::Config cfg = task == Task::kWalker ? qd::defaults_of(qd::bipedal::kWalkerParams, "environment")
                                               : qd::defaults_of(qd::bipedal::kKickerParams, "environment");
  const qd::bipedal::BipedalEnvironment env(task, cfg);
  const qd::PolicyShape shape = shape_for(task);
  constexpr int kN = 4;
  qd::Matrix params(kN, static_cast<Eigen::Index>(shape.param_count()));
  for (int i = 0; i < kN; ++i) {
    const std::vector<double> theta = random_params(task, 20 + static_cast<std::uint64_t>(i));
    for (std::size_t p = 0; p < theta.size(); ++p) params(i, static_cast<Eigen::Index>(p)) = theta[p];
  }
  const std::uint64_t seeds[kN] = {1, 2, 3, 4};
  auto batch = [&](std::size_t begin, std::size_t end) {
    qd::RolloutBatch b;
    b.shape = &shape;
    b.params = params.data();
    b.episode_seeds = seeds;
    b.begin = begin;
    b.end = end;
    return b;
  };
  std::vector<qd::Trace> first(kN), second(kN), forward(kN), backward(kN);
  env.rollout(batch(0, kN), first.data());
  env.rollout(batch(0, kN), second.data());
  std::thread t1([&] {
    for (std::size_t i = 0; i < kN; ++i) env.rollout(batch(i, i + 1), forward.data());
  });
  std::thread t2([&] {
    for (std::size_t i = kN; i-- > 0;) env.rollout(batch(i, i + 1), backward.data());
  });
  t1.join();
  t2.join();
  for (int i = 0; i < kN; ++i) {
    SCOPED_TRACE(i);
    EXPECT_GT(first[i].steps, 0);
    EXPECT_EQ(qd::testing::trace_difference(first[i], second[i]), "");
    EXPECT_EQ(qd::testing::trace_difference(first[i], forward[i]), "");
    EXPECT_EQ(qd::testing::trace_difference(first[i], backward[i]), "");
  }
}

TEST(BipedalWalker, DeterministicAcrossRunsAndThreads) {
  check_determinism(Task::kWalker);
}
TEST(BipedalKicker, DeterministicAcrossRunsAndThreads) {
  check_determinism(Task::kKicker);
}

// The shipped conformance checks (qd/testing), for both environments and all descriptor variants.
TEST(BipedalEnvironment, Conforms) {
  const qd::bipedal::WalkerEnvironment walker(qd::defaults_of(qd::bipedal::kWalkerParams, "environment"), {});
  const qd::bipedal::KickerEnvironment kicker(qd::defaults_of(qd::bipedal::kKickerParams, "environment"), {});
  qd::testing::EnvironmentOptions options;
  options.hidden = {32, 32};
  for (const qd::Environment* env :
       {static_cast<const qd::Environment*>(&walker), static_cast<const qd::Environment*>(&kicker)}) {
    const qd::testing::Report report = qd::testing::check_environment(*env, options);
    EXPECT_TRUE(report.ok()) << env->info().observation_size << " observations: " << report;
  }
}

TEST(BipedalDescriptors, Conform) {
  const qd::bipedal::WalkerEnvironment walker(qd::defaults_of(qd::bipedal::kWalkerParams, "environment"), {});
  const auto walks = qd::testing::rollout_all(walker, qd::testing::random_policies(walker, 24, {32, 32}));
  for (const char* bins : {"reference", "corrected"}) {
    qd::Config cfg = qd::defaults_of(qd::bipedal::kWalkerGaitParams, "descriptor");
    cfg.set_string("contact_bins", bins, "test");
    const qd::testing::Report report = qd::testing::check_descriptor(qd::bipedal::WalkerGaitDescriptor(cfg, {}), walks);
    EXPECT_TRUE(report.ok()) << bins << ": " << report;
  }
  const qd::bipedal::KickerEnvironment kicker(qd::defaults_of(qd::bipedal::kKickerParams, "environment"), {});
  const auto kicks = qd::testing::rollout_all(kicker, qd::testing::random_policies(kicker, 24, {32, 32}));
  const qd::testing::Report report =
      qd::testing::check_descriptor(qd::bipedal::KickerBallDescriptor(qd::Config("descriptor"), {}), kicks);
  EXPECT_TRUE(report.ok()) << report;
}

// ---- Audit against the paper and the reference sources (README "Audit") ---------------------------

constexpr double kThird = 1.0 / 3.0;

TEST(BipedalAudit, WorldAndTerrain) {
  for (Task task : {Task::kWalker, Task::kKicker}) {
    SCOPED_TRACE(task == Task::kWalker ? "walker" : "kicker");
    const qd::bipedal::SceneFacts f = qd::bipedal::scene_facts(task);
    EXPECT_EQ(f.gravity_y, -10.0);
    EXPECT_TRUE(f.allow_sleep);
    EXPECT_EQ(f.terrain_bodies, 199);  // one static body per edge, not a chain
    EXPECT_FLOAT_EQ(f.terrain_friction, task == Task::kWalker ? 2.5 : 0.9);
    EXPECT_EQ(f.terrain_category, 0x0001);
    EXPECT_EQ(f.terrain_mask, 0xFFFF);
    ASSERT_EQ(f.terrain_x.size(), 200u);
    const auto& h = qd::bipedal::walker_terrain_heights();
    for (std::size_t i = 0; i < 200; ++i) {
      EXPECT_FLOAT_EQ(f.terrain_x[i], static_cast<float>(i * 14.0 / 30.0)) << i;
      EXPECT_FLOAT_EQ(f.terrain_y[i], static_cast<float>(task == Task::kWalker ? h[i] : 10.0 / 3.0)) << i;
    }
  }
}

TEST(BipedalAudit, HullAndLegGeometry) {
  for (Task task : {Task::kWalker, Task::kKicker}) {
    SCOPED_TRACE(task == Task::kWalker ? "walker" : "kicker");
    const qd::bipedal::SceneFacts f = qd::bipedal::scene_facts(task);
    const double x0 = task == Task::kWalker ? 14.0 / 30.0 * 100 : 14.0 / 30.0 * 95;
    const std::uint16_t category = task == Task::kWalker ? 0x0020 : 0x0002;
    const std::uint16_t mask = task == Task::kWalker ? 0x0001 : 0x0005;
    EXPECT_NEAR(f.hull.x, x0, 1e-5);
    EXPECT_NEAR(f.hull.y, 10.0 / 3.0 + 2 * 34.0 / 30.0, 1e-6);  // 5.6
    EXPECT_EQ(f.hull.angle, 0.0);
    EXPECT_NEAR(f.hull.mass, 5.0 * 1.0844444, 1e-5);  // polygon area 1.0844, density 5
    EXPECT_FLOAT_EQ(f.hull.friction, 0.1);
    EXPECT_EQ(f.hull.restitution, 0.0);
    EXPECT_EQ(f.hull.category, category);
    EXPECT_EQ(f.hull.mask, mask);
    for (int k = 0; k < 4; ++k) {
      SCOPED_TRACE(k);
      const qd::bipedal::BodyFacts& leg = f.legs[k];
      const bool lower = (k % 2) == 1;
      EXPECT_TRUE(leg.dynamic);
      EXPECT_EQ(leg.fixtures, 1);
      EXPECT_NEAR(leg.x, x0, 1e-5);
      EXPECT_NEAR(leg.y, lower ? 5.6 - 1.5 * 34.0 / 30.0 + 8.0 / 30.0 : 5.6 - 17.0 / 30.0 + 8.0 / 30.0, 1e-6);
      EXPECT_FLOAT_EQ(leg.angle, k < 2 ? -0.05 : 0.05);
      EXPECT_NEAR(leg.mass, (lower ? 0.8 : 1.0) * 8.0 / 30.0 * 34.0 / 30.0, 1e-6);  // density 1
      EXPECT_FLOAT_EQ(leg.friction, 0.2);                                           // Box2D default
      EXPECT_EQ(leg.restitution, 0.0);
      EXPECT_EQ(leg.category, category);
      EXPECT_EQ(leg.mask, mask);
    }
    // Creation order (it fixes Box2D's body and contact order): terrain, hull, upper L, lower L,
    // upper R, lower R, then the ball.
    const std::vector<int> order =
        task == Task::kWalker ? std::vector<int>{0, 1, 2, 3, 4} : std::vector<int>{0, 1, 2, 3, 4, 5};
    EXPECT_EQ(f.creation_order, order);
  }
}

TEST(BipedalAudit, JointsAndMotors) {
  for (Task task : {Task::kWalker, Task::kKicker}) {
    const qd::bipedal::SceneFacts f = qd::bipedal::scene_facts(task);
    for (int j = 0; j < 4; ++j) {
      SCOPED_TRACE(j);
      const qd::bipedal::JointFacts& joint = f.joints[j];
      const bool knee = (j % 2) == 1;
      const int side = j < 2 ? -1 : 1;
      EXPECT_EQ(joint.body_a, knee ? j : 0);  // hip: hull -> upper leg; knee: upper -> lower leg
      EXPECT_EQ(joint.body_b, j + 1);
      EXPECT_EQ(joint.anchor_a[0], 0.0);
      EXPECT_FLOAT_EQ(joint.anchor_a[1], knee ? -17.0 / 30.0 : -8.0 / 30.0);
      EXPECT_EQ(joint.anchor_b[0], 0.0);
      EXPECT_FLOAT_EQ(joint.anchor_b[1], 17.0 / 30.0);
      EXPECT_EQ(joint.reference_angle, 0.0);  // keyword-filled def, no Initialize
      EXPECT_TRUE(joint.motor);
      EXPECT_TRUE(joint.limit);
      EXPECT_FLOAT_EQ(joint.lower, knee ? -1.6 : -0.8);
      EXPECT_FLOAT_EQ(joint.upper, knee ? -0.1 : 1.1);
      EXPECT_EQ(joint.max_motor_torque, 80.0);
      EXPECT_EQ(joint.motor_speed, knee ? 1.0 : side);
    }
  }
}

TEST(BipedalAudit, BallOnlyInTheKicker) {
  EXPECT_EQ(qd::bipedal::scene_facts(Task::kWalker).ball.fixtures, 0);
  const qd::bipedal::BodyFacts ball = qd::bipedal::scene_facts(Task::kKicker).ball;
  EXPECT_TRUE(ball.dynamic);
  EXPECT_EQ(ball.fixtures, 1);
  EXPECT_NEAR(ball.x, 14.0 / 30.0 * 100, 1e-5);
  EXPECT_NEAR(ball.y, 10.0 / 3.0 + 2 * kThird, 1e-6);                            // TERRAIN_HEIGHT + 2 r = 4.0
  EXPECT_NEAR(ball.mass, 0.5 * 3.14159265358979323846 * kThird * kThird, 1e-6);  // r = 10/30, density 0.5
  EXPECT_FLOAT_EQ(ball.friction, 0.1);
  EXPECT_FLOAT_EQ(ball.restitution, 0.7);
  EXPECT_EQ(ball.linear_damping, 1.0);
  EXPECT_EQ(ball.category, 0x0004);
  EXPECT_EQ(ball.mask, 0x0003);
}

TEST(BipedalAudit, InitialPushOnlyInTheWalker) {
  // The reset step runs with limp joints; the hull's horizontal speed after it differs between
  // the two tasks only by the walker's push of +2.3627539 N for one step (0.02 s), shared with
  // the legs through the joints: dv lies between F dt / (all five bodies) and F dt / hull.
  const Episode walker = run(Task::kWalker, std::vector<double>(2052, 0.0), false, 1);
  const Episode kicker = run(Task::kKicker, std::vector<double>(2180, 0.0), false, 1);
  const double dv = (walker.observations[2] - kicker.observations[2]) / 0.12;
  const double impulse = 2.3627539207 * 0.02;
  EXPECT_GT(dv, impulse / (5.4222 + 2 * (0.30222 + 0.24178)) * 0.99);
  EXPECT_LT(dv, impulse / 5.4222 * 1.01);
}

TEST(BipedalAudit, KickerLidarOnFlatGround) {
  // Ten rays from the hull origin along (sin a, -cos a), a = 1.5 i / 10, of length 160/30; only
  // the ground (category 1) is seen, so on flat ground the fraction is drop / (cos a * 160/30).
  const Episode e = run(Task::kKicker, std::vector<double>(2180, 0.0), false, 1);
  const float* obs = e.observations.data();
  const double drop = obs[25] - 10.0 / 3.0;
  int hits = 0;
  for (int i = 0; i < 10; ++i) {
    const double reach = std::cos(1.5 * i / 10.0) * 160.0 / 30.0;
    const double expected = drop <= reach ? drop / reach : 1.0;
    hits += drop <= reach ? 1 : 0;
    EXPECT_NEAR(obs[14 + i], expected, 2e-5) << "ray " << i;
  }
  EXPECT_EQ(hits, 8);  // rays 8 and 9 are too flat to reach the ground from 5.6
}

TEST(BipedalAudit, LidarRaysCrossTheWalkerTerrainAtMostOnce) {
  // The reference's lidar callback returns 0 (the first ground hit Box2D reports ends the ray),
  // ours returns the fraction (the closest hit). They agree when a ray cannot cross the ground
  // twice: every ray descends at least cot(1.35) = 0.224 per unit of x (ray 9, the flattest), so
  // it stays below the ground once under it if no terrain edge descends faster than that.
  const auto& h = qd::bipedal::walker_terrain_heights();
  const double steepest_ray = std::cos(1.35) / std::sin(1.35);
  double steepest_descent = 0.0;
  for (std::size_t i = 0; i + 1 < h.size(); ++i)
    steepest_descent = std::max(steepest_descent, (h[i] - h[i + 1]) / (14.0 / 30.0));
  EXPECT_NEAR(steepest_descent, 0.1667, 1e-4);
  EXPECT_LT(steepest_descent, steepest_ray);
}

// Known answer: the distribution of cells of a fixed set of U(-1, 1) policies (hidden [32, 32]).
// It pins the dynamics as a whole: a change of engine, geometry, contact rules, termination or
// binning moves it. Values measured with Debian's Box2D 2.4.1 on x86-64.
struct Distribution {
  int distinct = 0;
  int most_common_cell = -1;
  int most_common_count = 0;
  int terminations[9] = {};
  std::uint64_t hash = 1469598103934665603ull;  // FNV-1a over the sorted (cell, count) pairs
};

Distribution cell_distribution(Task task, int n) {
  std::map<std::int64_t, int> counts;
  Distribution d;
  for (int k = 0; k < n; ++k) {
    const Episode e = run(task, random_params(task, 5000 + static_cast<std::uint64_t>(k)));
    double v[4];
    const std::int64_t cell = task == Task::kWalker ? qd::bipedal::walker_gait_cell(e.trace, false, v)
                                                    : qd::bipedal::kicker_ball_cell(e.trace, v);
    ++counts[cell];
    ++d.terminations[e.trace.events.at(0)];
  }
  d.distinct = static_cast<int>(counts.size());
  for (const auto& [cell, count] : counts) {
    if (count > d.most_common_count) {
      d.most_common_count = count;
      d.most_common_cell = static_cast<int>(cell);
    }
    for (std::int64_t word : {cell, static_cast<std::int64_t>(count)}) {
      for (int b = 0; b < 8; ++b) {
        d.hash ^= static_cast<std::uint64_t>(word >> (8 * b)) & 0xFF;
        d.hash *= 1099511628211ull;
      }
    }
  }
  return d;
}

std::string describe(const Distribution& d) {
  std::ostringstream s;
  s << "distinct " << d.distinct << ", most common cell " << d.most_common_cell << " x" << d.most_common_count
    << ", terminations";
  for (int t : d.terminations) s << ' ' << t;
  s << ", hash 0x" << std::hex << d.hash;
  return s.str();
}

TEST(BipedalKnownAnswer, WalkerCellDistributionOf200RandomPolicies) {
  const Distribution d = cell_distribution(Task::kWalker, 200);
  EXPECT_EQ(describe(d),
            "distinct 96, most common cell 3749 x22, terminations 2 141 0 0 57 0 0 0 0, hash 0xee491738aaf5c6bd")
      << describe(d);
}

TEST(BipedalKnownAnswer, KickerCellDistributionOf200RandomPolicies) {
  const Distribution d = cell_distribution(Task::kKicker, 200);
  EXPECT_EQ(describe(d),
            "distinct 28, most common cell 0 x151, terminations 0 0 0 0 0 20 143 37 0, hash 0x9e4fda8c8a0b4ad0")
      << describe(d);
}

// ---- Ghost balls (the reference's kicker keeps every earlier episode's ball) ---------------------

Episode run_in(qd::bipedal::BallWorld& world, const std::vector<double>& theta) {
  qd::bipedal::warm_up_box2d();
  EpisodeOptions options;
  options.task = Task::kKicker;
  qd::Policy policy(shape_for(Task::kKicker));
  policy.load(theta.data());
  Episode e;
  qd::bipedal::run_episode(options, policy, e.trace, &e.observations, &world);
  return e;
}

// The first random policy (fixed stream) that moves the ball more than one unit in a fresh world.
std::vector<double> kicking_policy() {
  for (std::uint64_t key = 0;; ++key) {
    std::vector<double> theta = random_params(Task::kKicker, 1000 + key);
    const Episode e = run(Task::kKicker, theta);
    if (e.trace.main.last()[0] > qd::bipedal::kBallStartX + 1.0) return theta;
  }
}

bool same_trace(const qd::Trace& a, const qd::Trace& b) {
  return a.steps == b.steps && a.main.data == b.main.data && a.aux.data == b.aux.data && a.events == b.events;
}

// A robot that never reaches the ball meets no ghost (balls do not collide with balls, the lidar
// ignores them): it ends as in a fresh world, in the same cell with the same termination, and each
// episode leaves its ball at rest on the start position. Its trajectory may still differ in the
// last digits, as in the reference: the extra bodies change the broad-phase tree, hence the order
// in which Box2D creates and solves the robot's ground contacts.
TEST(BipedalGhostBalls, AnUntouchedBallStaysAndChangesNoCell) {
  const std::vector<double> limp(shape_for(Task::kKicker).param_count(), 0.0);
  const Episode fresh = run(Task::kKicker, limp);
  double fresh_values[2], values[2];
  const std::int64_t fresh_cell = qd::bipedal::kicker_ball_cell(fresh.trace, fresh_values);
  qd::bipedal::BallWorld world;
  EXPECT_EQ(world.balls(), 1u);  // the environment constructor's reset leaves the first one
  for (std::size_t k = 1; k <= 3; ++k) {
    const Episode e = run_in(world, limp);
    EXPECT_EQ(qd::bipedal::kicker_ball_cell(e.trace, values), fresh_cell) << "episode " << k;
    EXPECT_EQ(why(e.trace), why(fresh.trace)) << "episode " << k;
    EXPECT_EQ(e.trace.main.data, fresh.trace.main.data) << "episode " << k;  // the ball's own path
    EXPECT_EQ(world.balls(), k + 1);
  }
}

// A kick moves the ball and the ghost stacked on its start position together (a heavier ball):
// the kicked ball ends elsewhere than in a fresh world, and both balls end off the start.
TEST(BipedalGhostBalls, AKickMovesTheStackAtTheStart) {
  const std::vector<double> kicker = kicking_policy();
  const double fresh_x = run(Task::kKicker, kicker).trace.main.last()[0];
  qd::bipedal::BallWorld world;
  const Episode e = run_in(world, kicker);
  EXPECT_NE(e.trace.main.last()[0], fresh_x);
  std::stringstream state;
  world.save(state);
  std::uint32_t tag;
  std::uint64_t n;
  state.read(reinterpret_cast<char*>(&tag), sizeof tag).read(reinterpret_cast<char*>(&n), sizeof n);
  ASSERT_EQ(n, 2u);  // the constructor's ball and this episode's
  for (std::uint64_t k = 0; k < n; ++k) {
    float f[6];
    std::uint8_t awake;
    state.read(reinterpret_cast<char*>(f), sizeof f).read(reinterpret_cast<char*>(&awake), 1);
    EXPECT_GT(f[0], qd::bipedal::kBallStartX + 0.1) << "ball " << k;
  }
}

// The core reloads the worlds from every checkpoint: a world saved and loaded twice continues as
// one loaded once (what a resumed run does), episode for episode.
TEST(BipedalGhostBalls, AReloadedWorldContinuesAsAResumedOne) {
  const std::vector<double> kicker = kicking_policy();
  qd::bipedal::BallWorld original;
  for (std::uint64_t k = 0; k < 3; ++k) run_in(original, k == 1 ? kicker : random_params(Task::kKicker, 50 + k));
  std::stringstream saved;
  original.save(saved);
  const std::string bytes = saved.str();
  qd::bipedal::BallWorld resumed;
  std::istringstream a(bytes), b(bytes);
  original.load(a);
  resumed.load(b);
  EXPECT_EQ(resumed.balls(), 4u);
  for (std::uint64_t k = 0; k < 3; ++k) {
    const std::vector<double> theta = k == 0 ? kicker : random_params(Task::kKicker, 60 + k);
    EXPECT_TRUE(same_trace(run_in(original, theta).trace, run_in(resumed, theta).trace)) << "episode " << k;
  }
  std::stringstream s1, s2;
  original.save(s1);
  resumed.save(s2);
  EXPECT_EQ(s1.str(), s2.str());
  std::istringstream junk("not a world");
  EXPECT_THROW(resumed.load(junk), qd::StateError);
  // A state that claims 2^32 balls and holds four ends early, before anything of its size is allocated.
  std::string claims = bytes;
  const std::uint64_t huge = std::uint64_t{1} << 32;
  claims.replace(4, sizeof huge, reinterpret_cast<const char*>(&huge), sizeof huge);
  std::istringstream lying(claims);
  const std::size_t before = resumed.balls();
  try {
    resumed.load(lying);
    ADD_FAILURE() << "a state with 4 of 2^32 balls loaded";
  } catch (const qd::StateError& e) {
    EXPECT_STREQ(e.what(), "state blob ends early");
  }
  EXPECT_EQ(resumed.balls(), before);  // a failed load leaves the world as it was
}

// The environment: ghost_balls = N is N persistent worlds for the core; world -1 (replays, the
// dry-run's pilot) is a fresh world; a world out of range or several rows per call is refused.
TEST(BipedalGhostBalls, EnvironmentKeysAndWorlds) {
  qd::Config cfg = qd::defaults_of(qd::bipedal::kKickerParams, "environment");
  EXPECT_EQ(qd::bipedal::KickerEnvironment(cfg, {}).info().persistent_worlds, 0);
  for (const qd::ParamSpec& p : qd::bipedal::kWalkerParams) EXPECT_STRNE(p.key, "ghost_balls");
  cfg.set_int("ghost_balls", 3);
  qd::bipedal::KickerEnvironment env(cfg, {});
  EXPECT_EQ(env.info().persistent_worlds, 3);
  const qd::PolicyShape shape = shape_for(Task::kKicker);
  const std::vector<double> theta = kicking_policy();
  const std::uint64_t seed = 0;
  std::vector<qd::Trace> traces(2);
  qd::RolloutBatch batch{&shape, theta.data(), &seed, 0, 1, -1};
  env.rollout(batch, traces.data());
  EXPECT_TRUE(same_trace(traces[0], run(Task::kKicker, theta).trace));
  batch.world = 2;
  env.rollout(batch, traces.data());
  EXPECT_NE(traces[0].main.last()[0], run(Task::kKicker, theta).trace.main.last()[0]);
  std::stringstream state;
  env.save(state);
  qd::bipedal::KickerEnvironment other(cfg, {});
  other.load(state);
  batch.world = 3;
  EXPECT_THROW(env.rollout(batch, traces.data()), std::invalid_argument);
  cfg.set_int("ghost_balls", 2);
  qd::bipedal::KickerEnvironment two(cfg, {});
  std::stringstream again;
  env.save(again);
  EXPECT_THROW(two.load(again), qd::StateError);
}

TEST(BipedalEnvironment, InfoAndSvg) {
  const qd::bipedal::BipedalEnvironment walker(Task::kWalker,
                                               qd::defaults_of(qd::bipedal::kWalkerParams, "environment"));
  EXPECT_EQ(walker.info().observation_size, 26);
  EXPECT_EQ(walker.info().action_size, 4);
  EXPECT_EQ(walker.info().max_steps, 500);
  const qd::bipedal::BipedalEnvironment kicker(Task::kKicker,
                                               qd::defaults_of(qd::bipedal::kKickerParams, "environment"));
  EXPECT_EQ(kicker.info().observation_size, 30);
  const Episode e = run(Task::kKicker, random_params(Task::kKicker, 4));
  std::ostringstream svg;
  EXPECT_TRUE(kicker.draw_svg(e.trace, svg));
  EXPECT_NE(svg.str().find("<svg"), std::string::npos);
  EXPECT_NE(svg.str().find("</svg>"), std::string::npos);
}

}  // namespace
