// Striker environment and contact-grid descriptor: known answers from the reference's behaviour
// (README.md) and from its float64 arithmetic.
#include "striker_descriptor.hpp"
#include "striker_env.hpp"
#include "striker_sim.hpp"

#include <qd/rng.hpp>
#include <qd/testing/conformance.hpp>

#include <box2d/box2d.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <thread>
#include <vector>

namespace {

using qd::striker::ContactGridDescriptor;
using qd::striker::Observation;
using qd::striker::Options;
using qd::striker::StrikerEnvironment;

const qd::PolicyShape& striker_shape() {
  static const qd::PolicyShape shape(14, {32, 32}, 3);
  return shape;
}

// Parameters of a policy whose output is the constant `action`: every weight is zero, so the
// hidden layers are tanh(0) = 0 and the output is exactly the output-layer bias.
std::vector<double> constant_policy(double a0, double a1, double a2) {
  const auto& shape = striker_shape();
  std::vector<double> theta(shape.param_count(), 0.0);
  const int last = shape.layers() - 1;
  const std::size_t bias = shape.layer_offset(last) + static_cast<std::size_t>(shape.layer_inputs(last) * 3);
  theta[bias + 0] = a0;
  theta[bias + 1] = a1;
  theta[bias + 2] = a2;
  return theta;
}

qd::Trace run(const std::vector<double>& theta, const Options& options = {},
              std::vector<Observation>* observations = nullptr) {
  qd::Policy policy(striker_shape());
  qd::Trace trace;
  qd::striker::run_policy_episode(options, policy, theta.data(), trace, observations);
  return trace;
}

std::int64_t describe_cell(const qd::Trace& trace, double* values_out = nullptr) {
  ContactGridDescriptor descriptor;
  std::int64_t cell = -2;
  double values[3];
  descriptor.describe(&trace, 1, &cell, values);
  if (values_out) std::memcpy(values_out, values, sizeof values);
  return cell;
}

qd::Trace synthetic_trace(std::vector<int> events, double x, double y) {
  qd::Trace trace;
  trace.main.reset(2);
  trace.main.push(0.0, 0.0);
  trace.main.push(x, y);
  trace.events = std::move(events);
  return trace;
}

// ---- Policy and plugin surface -------------------------------------------------------------

TEST(StrikerPolicy, ParamCount) {
  EXPECT_EQ(qd::PolicyShape(14, {32, 32}, 3).param_count(), 1635u);
}

TEST(StrikerEnvironment, InfoAndDefaults) {
  const qd::Config config = qd::defaults_of(qd::striker::kEnvironmentParams, "environment");
  StrikerEnvironment env(config, qd::BuildContext{});
  const qd::EnvironmentInfo info = env.info();
  EXPECT_EQ(info.observation_size, 14);
  EXPECT_EQ(info.action_size, 3);
  EXPECT_EQ(info.max_steps, 1000);
  EXPECT_FALSE(env.options().mix_scale);
  EXPECT_FALSE(env.options().puck_hits_target);
}

// ---- Descriptor -----------------------------------------------------------------------------

TEST(StrikerDescriptor, GridSpec) {
  const qd::GridSpec grid = ContactGridDescriptor().grid();
  EXPECT_EQ(grid.shape, (std::vector<std::int64_t>{17, 30, 30}));
  EXPECT_EQ(grid.names, (std::vector<std::string>{"walls", "y", "x"}));
  EXPECT_EQ(grid.cells, 15300);
  EXPECT_DOUBLE_EQ(grid.lower[1], -0.465);
  EXPECT_DOUBLE_EQ(grid.upper[1], 1.465);
  EXPECT_DOUBLE_EQ(grid.lower[2], -0.965);
  EXPECT_DOUBLE_EQ(grid.upper[2], 0.965);
}

// The wall classes are named in grid.toml, in the order of the class index (the reference's figure
// titles): first wall touched, then the second; S = 0, E = 1, N = 2, W = 3.
TEST(StrikerDescriptor, WallClassLabels) {
  const qd::GridSpec grid = ContactGridDescriptor().grid();
  ASSERT_EQ(grid.labels.size(), 3u);
  EXPECT_EQ(grid.labels[0], (std::vector<std::string>{"none", "S", "E", "N", "W", "S-E", "S-N", "S-W", "E-S", "E-N",
                                                      "E-W", "N-S", "N-E", "N-W", "W-S", "W-E", "W-N"}));
  EXPECT_TRUE(grid.labels[1].empty());
  EXPECT_TRUE(grid.labels[2].empty());
  const int north_then_west[] = {2, 2, 3, 0};
  EXPECT_EQ(grid.labels[0][qd::striker::wall_class(north_then_west, 4)], "N-W");
}

// The grid describes the cell index: decomposed row-major over its shape (as grid.toml readers do),
// a cell gives the wall class, the y bin and the x bin, in the order of the names.
TEST(StrikerDescriptor, GridDecomposesTheCellIndex) {
  const qd::GridSpec grid = ContactGridDescriptor().grid();
  const std::int64_t cell = qd::striker::cell_index(9, 4, 27);  // class E-N, px 4, py 27
  std::int64_t rest = cell;
  std::vector<std::int64_t> bins(grid.shape.size());
  for (std::size_t d = grid.shape.size(); d-- > 0;) {
    bins[d] = rest % grid.shape[d];
    rest /= grid.shape[d];
  }
  EXPECT_EQ(bins, (std::vector<std::int64_t>{9, 27, 4}));
  EXPECT_EQ(grid.names[1], "y");
  EXPECT_EQ(grid.names[2], "x");
}

TEST(StrikerDescriptor, AllSeventeenWallClasses) {
  struct Case {
    std::vector<int> events;
    int expected;
  };
  // Walls: 0 S, 1 E, 2 N, 3 W. README.md: S-E 5, S-N 6, S-W 7, E-S 8, E-N 9, E-W 10, N-S 11, N-E 12,
  // N-W 13, W-S 14, W-E 15, W-N 16.
  const std::vector<Case> cases = {
      {{}, 0},      {{0}, 1},     {{1}, 2},     {{2}, 3},     {{3}, 4},     {{0, 1}, 5},
      {{0, 2}, 6},  {{0, 3}, 7},  {{1, 0}, 8},  {{1, 2}, 9},  {{1, 3}, 10}, {{2, 0}, 11},
      {{2, 1}, 12}, {{2, 3}, 13}, {{3, 0}, 14}, {{3, 1}, 15}, {{3, 2}, 16},
  };
  std::vector<bool> seen(17, false);
  for (const Case& c : cases) {
    EXPECT_EQ(qd::striker::wall_class(c.events.data(), c.events.size()), c.expected);
    seen[static_cast<std::size_t>(c.expected)] = true;
  }
  for (int g = 0; g < 17; ++g) EXPECT_TRUE(seen[static_cast<std::size_t>(g)]) << g;
}

TEST(StrikerDescriptor, RepeatedAndLaterWalls) {
  auto cls = [](std::vector<int> e) { return qd::striker::wall_class(e.data(), e.size()); };
  EXPECT_EQ(cls({1, 1, 0}), 8);         // repeated E then S: E-S
  EXPECT_EQ(cls({2, 2, 2}), 3);         // only N, touched three times
  EXPECT_EQ(cls({0, 1, 2}), 5);         // third wall ignored: S-E
  EXPECT_EQ(cls({3, 3, 1, 0, 2}), 15);  // W-E
  EXPECT_EQ(cls({0, 0, 0, 3, 0, 3}), 7);
  EXPECT_EQ(cls({4}), -1);  // not a wall
  EXPECT_EQ(cls({-1}), -1);
}

TEST(StrikerDescriptor, BinEdges) {
  using qd::striker::bin_x;
  using qd::striker::bin_y;
  EXPECT_EQ(bin_x(-0.965), 0);
  EXPECT_EQ(bin_x(0.965), 29);  // (0.965 + 0.965) / 1.93 * 30 = 30, clipped to 29
  EXPECT_EQ(bin_x(-5.0), 0);
  EXPECT_EQ(bin_x(5.0), 29);
  EXPECT_EQ(bin_x(0.0), 15);     // exactly on the 14|15 boundary: 15.0
  EXPECT_EQ(bin_x(-1e-12), 14);  // just below it
  // Values the reference computes as exact boundaries, and one its float64 arithmetic puts just
  // below (k = 3: -0.772 -> 2.999999999999999 -> bin 2; k = 27: 0.7719999999999999 -> bin 26).
  EXPECT_EQ(bin_x(-0.32166666666666666), 10);
  EXPECT_EQ(bin_x(-0.772), 2);
  EXPECT_EQ(bin_x(0.7719999999999999), 26);
  EXPECT_EQ(bin_y(-0.465), 0);
  EXPECT_EQ(bin_y(1.465), 29);
  EXPECT_EQ(bin_y(0.0), 7);  // 0.465 / 1.93 * 30 = 7.23
  EXPECT_EQ(bin_y(-3.0), 0);
  EXPECT_EQ(bin_y(3.0), 29);
  EXPECT_EQ(bin_x(std::numeric_limits<double>::quiet_NaN()), -1);
}

TEST(StrikerDescriptor, CellFormulaAndValues) {
  double values[3];
  // W-N (16), x 0.5 -> px 22, y 1.0 -> py 22: 16 * 900 + 22 * 30 + 22.
  EXPECT_EQ(describe_cell(synthetic_trace({3, 2}, 0.5, 1.0), values), 15082);
  EXPECT_EQ(values[0], 16.0);
  EXPECT_EQ(values[1], 0.5);
  EXPECT_EQ(values[2], 1.0);
  // Class 0 at the puck's start: px 15, py 7.
  EXPECT_EQ(describe_cell(synthetic_trace({}, 0.0, 0.0)), 225);
  // Corners of the grid.
  EXPECT_EQ(describe_cell(synthetic_trace({}, -2.0, -2.0)), 0);
  EXPECT_EQ(describe_cell(synthetic_trace({3, 2, 1}, 2.0, 2.0)), 15299);
  EXPECT_EQ(qd::striker::cell_index(8, 3, 4), 8 * 900 + 4 * 30 + 3);
}

TEST(StrikerDescriptor, UndescribableTraces) {
  qd::Trace empty;
  empty.main.reset(2);
  EXPECT_EQ(describe_cell(empty), -1);
  EXPECT_EQ(describe_cell(synthetic_trace({5}, 0.0, 0.0)), -1);
  EXPECT_EQ(describe_cell(synthetic_trace({}, std::nan(""), 0.0)), -1);
}

// ---- Episodes -------------------------------------------------------------------------------

TEST(StrikerEpisode, FirstObservationIsTheStartState) {
  std::vector<Observation> obs;
  run(constant_policy(0, 0, 0), {}, &obs);
  ASSERT_FALSE(obs.empty());
  const Observation expected = {0.0f, -0.3f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.5f, 1.0f, 1.5f, 1.0f};
  for (int i = 0; i < 14; ++i)
    EXPECT_EQ(obs[0][static_cast<std::size_t>(i)], expected[static_cast<std::size_t>(i)]) << i;
}

// All-zero parameters give action 0. At step 0 the puck is at rest (speed 0 <= 0.009) and the
// scaled action norm is 0 <= 0.009, so done is true after the very first world step: 1 step,
// rows = reset row + the step-0 row, no contact, puck at (0, 0) -> class 0, px 15, py 7 -> 225.
TEST(StrikerEpisode, ZeroActionEndsAtStepZero) {
  StrikerEnvironment env(Options{});
  qd::Matrix params = qd::Matrix::Zero(1, 1635);
  qd::RolloutBatch batch;
  batch.shape = &striker_shape();
  batch.params = params.data();
  batch.begin = 0;
  batch.end = 1;
  qd::Trace trace;
  env.rollout(batch, &trace);
  EXPECT_EQ(trace.status, qd::EvalStatus::kOk);
  EXPECT_EQ(trace.steps, 1);
  ASSERT_EQ(trace.main.rows(), 2u);
  ASSERT_EQ(trace.aux.rows(), 2u);
  EXPECT_EQ(trace.main.at(1, 0), 0.0);
  EXPECT_EQ(trace.main.at(1, 1), 0.0);
  EXPECT_EQ(trace.aux.at(0, 1), -0.3);
  EXPECT_TRUE(trace.events.empty());
  EXPECT_EQ(trace.fitness, -1.0);  // both aux rows are (0, -0.3, 0)
  EXPECT_EQ(describe_cell(trace), 225);
}

// A miss: the striker moves up and right past the puck. The puck never moves, so the episode can
// only end through the zero-action clause, which first holds at the 103rd call (step 102), when
// the reference zeroes the action.
TEST(StrikerEpisode, MissEndsWhenTheActionIsCutOff) {
  std::vector<Observation> obs;
  const qd::Trace trace = run(constant_policy(0.2, 0.3, 0.0), {}, &obs);
  EXPECT_EQ(trace.status, qd::EvalStatus::kOk);
  EXPECT_EQ(trace.steps, 103);
  EXPECT_TRUE(trace.events.empty());
  // Rows: reset, steps 0, 20, ..., 100, and the done row of step 102.
  EXPECT_EQ(trace.main.rows(), 8u);
  EXPECT_EQ(describe_cell(trace), 225);
  // While active the striker moves at exactly (2, 3) units/s; from step 102 on it is stopped.
  // (The observation is taken after the step, so it includes one step of linear damping 0.05.)
  EXPECT_NEAR(obs[102][5], 2.0 / (1.0 + 0.04 * 0.05), 1e-5);
  EXPECT_NEAR(obs[102][6], 3.0 / (1.0 + 0.04 * 0.05), 1e-5);
  EXPECT_EQ(obs[103][5], 0.0f);
  EXPECT_EQ(obs[103][6], 0.0f);
}

// The striker drives straight up at 4 units/s, meets the puck after (22.5 - 12.5) / 4 = 2.5 s,
// pushes it until the action is cut off at step 102, and the puck then coasts up with linear
// damping 0.05. It reaches the N wall at about 0.73 units/s, below Box2D's restitution threshold
// of 1 unit/s, so it does not bounce: its speed drops to <= 0.009 and the episode ends before
// 1000 steps, resting against the N wall (centre at y = 99 - 2.5 -> y_n = 1.43).
TEST(StrikerEpisode, PuckPushedIntoTheNorthWallStops) {
  std::vector<Observation> obs;
  const qd::Trace trace = run(constant_policy(0.0, 0.4, 0.0), {}, &obs);
  EXPECT_EQ(trace.status, qd::EvalStatus::kOk);
  EXPECT_GT(trace.steps, 102);
  EXPECT_LT(trace.steps, 960);  // so the done row survives the truncation
  EXPECT_EQ(trace.steps, 956);  // regression value (Debian Box2D 2.4.1)
  EXPECT_EQ(trace.events, std::vector<int>{2});
  const double* last = trace.main.last();
  EXPECT_EQ(last[0], 0.0);  // no sideways force at all
  EXPECT_NEAR(last[1], 1.43, 2e-4);
  // The last row is the done row: the state after the last step, puck at rest.
  EXPECT_EQ(static_cast<float>(last[1]), obs.back()[4]);
  EXPECT_LE(std::hypot(obs.back()[8], obs.back()[9]), 0.009f);
  // Rows: reset, steps 0, 20, ..., 940 (48 rows) and the done row = 50.
  EXPECT_EQ(trace.main.rows(), 50u);
  // Class N (3), px 15, py 29.
  EXPECT_EQ(describe_cell(trace), 3 * 900 + 29 * 30 + 15);
}

// Driven up at full speed the puck bounces off the N wall at ~0.8 units/s and is still moving at
// step 1000: the episode runs to the limit, 51 rows are recorded and the first 50 kept, so the
// final position is the state after step 960.
TEST(StrikerEpisode, RowsAreTruncatedAtStep960) {
  std::vector<Observation> obs;
  const qd::Trace trace = run(constant_policy(0.0, 1.0, 0.0), {}, &obs);
  EXPECT_EQ(trace.status, qd::EvalStatus::kOk);
  EXPECT_EQ(trace.steps, 1000);
  ASSERT_EQ(trace.main.rows(), 50u);
  ASSERT_EQ(trace.aux.rows(), 50u);
  EXPECT_EQ(trace.main.at(0, 0), 0.0);
  EXPECT_EQ(trace.main.at(0, 1), 0.0);
  EXPECT_EQ(trace.aux.at(0, 0), 0.0);
  EXPECT_EQ(trace.aux.at(0, 1), -0.3);
  EXPECT_EQ(trace.aux.at(0, 2), 0.0);
  ASSERT_EQ(obs.size(), 1001u);  // reset + one per step
  // Row r >= 1 is the state after step 20 (r - 1); obs[k + 1] is the state after step k.
  for (std::size_t r = 1; r < 50; ++r) {
    EXPECT_EQ(static_cast<float>(trace.main.at(r, 0)), obs[20 * (r - 1) + 1][3]) << r;
    EXPECT_EQ(static_cast<float>(trace.main.at(r, 1)), obs[20 * (r - 1) + 1][4]) << r;
  }
  EXPECT_NE(obs[961][4], obs[1000][4]);  // the dropped rows would have moved the final position
  EXPECT_EQ(trace.events, std::vector<int>{2});
}

// Runs an observation-independent policy (all weights zero) with and without mix-scale, so both
// runs follow the same physics; it turns, hits the puck and the puck touches walls, so every
// observation entry varies. Checks that exactly the `scaled` entries are multiplied by 100.
void check_mix_scale(qd::striker::MixScaleElements elements, const std::array<bool, 14>& scaled) {
  const std::vector<double> theta = constant_policy(0.0, 0.45, 0.5);
  Options mix;
  mix.mix_scale = true;
  mix.mix_scale_elements = elements;
  std::vector<Observation> plain_obs, mix_obs;
  const qd::Trace plain_trace = run(theta, {}, &plain_obs);
  const qd::Trace mix_trace = run(theta, mix, &mix_obs);
  EXPECT_EQ(qd::testing::trace_difference(plain_trace, mix_trace), "");
  EXPECT_GE(plain_trace.events.size(), 2u);
  ASSERT_EQ(plain_obs.size(), mix_obs.size());
  ASSERT_GT(plain_obs.size(), 500u);
  for (std::size_t k = 0; k < plain_obs.size(); ++k)
    for (std::size_t i = 0; i < 14; ++i) {
      const float expected = scaled[i] ? 100.0f * plain_obs[k][i] : plain_obs[k][i];
      ASSERT_EQ(mix_obs[k][i], expected) << "step " << k << " entry " << i;
    }
  std::array<bool, 14> listed{};
  for (int i : qd::striker::mix_scaled_entries(elements)) listed[static_cast<std::size_t>(i)] = true;
  EXPECT_EQ(listed, scaled);
  // The puck really moved, so the scaled entries were exercised away from their start values.
  EXPECT_GT(std::fabs(plain_obs.back()[4]), 0.5f);
  EXPECT_TRUE(std::any_of(plain_obs.begin(), plain_obs.end(),
                          [](const Observation& o) { return std::fabs(o[8]) > 1.0f && std::fabs(o[9]) > 1.0f; }));
}

TEST(StrikerEpisode, MixScaleCompanionScalesPuckPositionAndWallDistancesOnly) {
  check_mix_scale(qd::striker::MixScaleElements::kCompanion,
                  {false, false, false, true, true, false, false, false, false, false, true, true, true, true});
  Options mix;
  mix.mix_scale = true;
  std::vector<Observation> obs;
  run(constant_policy(0.0, 0.45, 0.5), mix, &obs);
  EXPECT_EQ(obs[0][10], 50.0f);
  EXPECT_EQ(obs[0][12], 150.0f);
}

TEST(StrikerEpisode, MixScalePaperScalesStrikerPositionAndPuckPositionAndVelocityOnly) {
  check_mix_scale(qd::striker::MixScaleElements::kPaper,
                  {true, true, false, true, true, false, false, false, true, true, false, false, false, false});
  Options mix;
  mix.mix_scale = true;
  mix.mix_scale_elements = qd::striker::MixScaleElements::kPaper;
  std::vector<Observation> obs;
  run(constant_policy(0.0, 0.45, 0.5), mix, &obs);
  EXPECT_FLOAT_EQ(obs[0][1], -30.0f);  // striker start y_n = -0.3
  EXPECT_EQ(obs[0][10], 0.5f);         // wall distances unscaled
}

TEST(StrikerEnvironment, MixScaleElementsOption) {
  qd::Config config = qd::defaults_of(qd::striker::kEnvironmentParams, "environment");
  EXPECT_EQ(StrikerEnvironment(config, qd::BuildContext{}).options().mix_scale_elements,
            qd::striker::MixScaleElements::kCompanion);
  config.set_string("mix_scale_elements", "paper");
  EXPECT_EQ(StrikerEnvironment(config, qd::BuildContext{}).options().mix_scale_elements,
            qd::striker::MixScaleElements::kPaper);
}

TEST(StrikerEpisode, PuckHitsTargetOption) {
  // Pushed up while the striker turns, the puck's path crosses the target circle at (25, 75),
  // radius 10. With the reference filter it passes through the target; with puck_hits_target it
  // cannot get closer than the sum of the radii (12.5, less Box2D's slop).
  const std::vector<double> theta = constant_policy(-0.15, 0.7, 0.5);
  Options hits;
  hits.puck_hits_target = true;
  auto closest_to_target = [](const std::vector<Observation>& obs) {
    double closest = 1e9;
    for (const Observation& o : obs)
      closest = std::min(closest, std::hypot(qd::striker::world_x(o[3]) - 25.0, qd::striker::world_y(o[4]) - 75.0));
    return closest;
  };
  std::vector<Observation> through_obs, hit_obs;
  const qd::Trace through = run(theta, {}, &through_obs);
  const qd::Trace hit = run(theta, hits, &hit_obs);
  EXPECT_LT(closest_to_target(through_obs), 10.0);  // the puck centre was inside the target
  EXPECT_GT(closest_to_target(hit_obs), 12.4);
  EXPECT_NE(through.main.last()[0], hit.main.last()[0]);
}

TEST(StrikerEpisode, NonFiniteActionIsInvalid) {
  std::vector<double> theta = constant_policy(0.0, 0.5, 0.0);
  theta[theta.size() - 1] = std::numeric_limits<double>::quiet_NaN();
  qd::Trace trace = run(theta);
  EXPECT_EQ(trace.status, qd::EvalStatus::kInvalidAction);
  EXPECT_EQ(trace.steps, 0);
  theta[theta.size() - 1] = std::numeric_limits<double>::infinity();
  trace = run(theta);
  EXPECT_EQ(trace.status, qd::EvalStatus::kInvalidAction);
}

// ---- Determinism ----------------------------------------------------------------------------

TEST(StrikerEpisode, DeterministicAcrossRepeatsAndThreads) {
  constexpr int kRows = 12;
  qd::Matrix params(kRows, 1635);
  qd::Rng rng(7, qd::Stream::kPlugin, 1);
  rng.fill_uniform(params.data(), static_cast<std::size_t>(params.size()), -1.0, 1.0);
  // Mix in policies that hit the puck, so long episodes with contacts are compared too.
  const std::vector<double> hits[] = {constant_policy(0, 0.4, 0), constant_policy(0.05, 0.45, 0.5),
                                      constant_policy(-0.15, 0.7, 0.5), constant_policy(0.2, 1.0, 0.5)};
  for (int i = 0; i < 4; ++i) params.row(i) = Eigen::Map<const qd::RowVector>(hits[i].data(), 1635);

  StrikerEnvironment env(Options{});
  auto batch_for = [&](std::size_t begin, std::size_t end) {
    qd::RolloutBatch batch;
    batch.shape = &striker_shape();
    batch.params = params.data();
    batch.begin = begin;
    batch.end = end;
    return batch;
  };
  std::vector<qd::Trace> first(kRows), second(kRows), threaded(kRows);
  env.rollout(batch_for(0, kRows), first.data());
  env.rollout(batch_for(0, kRows), second.data());
  // Two threads, each running its rows one at a time in descending order, interleaved.
  auto worker = [&](int parity) {
    for (int i = kRows - 1; i >= 0; --i)
      if (i % 2 == parity)
        env.rollout(batch_for(static_cast<std::size_t>(i), static_cast<std::size_t>(i) + 1), threaded.data());
  };
  std::thread a(worker, 0), b(worker, 1);
  a.join();
  b.join();
  int moved = 0;
  for (int i = 0; i < kRows; ++i) {
    EXPECT_EQ(qd::testing::trace_difference(first[static_cast<std::size_t>(i)], second[static_cast<std::size_t>(i)]),
              "")
        << i;
    EXPECT_EQ(qd::testing::trace_difference(first[static_cast<std::size_t>(i)], threaded[static_cast<std::size_t>(i)]),
              "")
        << i;
    moved += !first[static_cast<std::size_t>(i)].events.empty();
  }
  EXPECT_GE(moved, 3);
}

// ---- Conformance (qd/testing) ---------------------------------------------------------------

TEST(StrikerEnvironment, Conforms) {
  const StrikerEnvironment env(qd::defaults_of(qd::striker::kEnvironmentParams, "environment"), {});
  qd::testing::EnvironmentOptions options;
  options.hidden = {32, 32};
  const qd::testing::Report report = qd::testing::check_environment(env, options);
  EXPECT_TRUE(report.ok()) << report;
}

TEST(StrikerDescriptor, Conforms) {
  const StrikerEnvironment env(Options{});
  qd::testing::PolicyBatch batch = qd::testing::random_policies(env, 40, {32, 32});
  // Random policies rarely reach the puck: add some that hit it, so traces with contacts are described.
  const std::vector<double> hits[] = {constant_policy(0, 0.4, 0), constant_policy(0.05, 0.45, 0.5),
                                      constant_policy(-0.15, 0.7, 0.5), constant_policy(0.2, 1.0, 0.5)};
  for (int i = 0; i < 4; ++i) batch.params.row(i) = Eigen::Map<const qd::RowVector>(hits[i].data(), 1635);
  const qd::testing::Report report =
      qd::testing::check_descriptor(ContactGridDescriptor(), qd::testing::rollout_all(env, batch));
  EXPECT_TRUE(report.ok()) << report;
}

// ---- Misc -----------------------------------------------------------------------------------

TEST(StrikerEnvironment, DrawsSvg) {
  StrikerEnvironment env(Options{});
  const qd::Trace trace = run(constant_policy(0.05, 0.45, 0.5));
  std::ostringstream svg;
  ASSERT_TRUE(env.draw_svg(trace, svg));
  const std::string text = svg.str();
  EXPECT_EQ(text.rfind("<svg", 0), 0u);
  EXPECT_NE(text.find("<circle cx=\"25\" cy=\"75\" r=\"10\""), std::string::npos);  // target
  EXPECT_EQ(text.find("nan"), std::string::npos);
  EXPECT_NE(text.find("</svg>"), std::string::npos);
}

TEST(StrikerFitness, HalfPrecisionRounding) {
  using qd::striker::to_half_bits;
  EXPECT_EQ(to_half_bits(0.0), 0x0000);
  EXPECT_EQ(to_half_bits(1.0), 0x3c00);
  EXPECT_EQ(to_half_bits(-2.0), 0xc000);
  EXPECT_EQ(to_half_bits(65504.0), 0x7bff);
  EXPECT_EQ(to_half_bits(65520.0), 0x7c00);
  EXPECT_EQ(to_half_bits(0x1p-24), 0x0001);
  EXPECT_EQ(to_half_bits(0x1p-25), 0x0000);            // tie to even
  EXPECT_EQ(to_half_bits(1.0 + 0x1p-11), 0x3c00);      // tie to even (down)
  EXPECT_EQ(to_half_bits(1.0 + 3 * 0x1p-11), 0x3c02);  // tie to even (up)
  EXPECT_EQ(to_half_bits(-0.3), 0xb4cd);
  qd::Series aux;
  aux.reset(3);
  aux.push(0.0, -0.3, 0.0);
  aux.push(0.0, -0.30001, 0.0);  // same float16 row
  aux.push(0.0, -0.31, 0.0);
  aux.push(-0.0, -0.3, 0.0);  // -0 equals +0
  EXPECT_EQ(qd::striker::reference_fitness(aux), -2.0);
}

}  // namespace

// ---- Box2D's step timers (environments/common/box2d_profiling_off.cpp) ----------------------

// The replacement timers are what libbox2d calls from this binary, as from the plugin: a world
// step reports zero profiling time, and episodes are unchanged (the known answers above).
TEST(Box2dProfilingOff, TheLibraryStepsWithoutReadingTheClock) {
  b2World world(b2Vec2(0.0f, -10.0f));
  b2BodyDef def;
  def.type = b2_dynamicBody;
  b2Body* body = world.CreateBody(&def);
  b2PolygonShape box;
  box.SetAsBox(1.0f, 1.0f);
  body->CreateFixture(&box, 1.0f);
  for (int i = 0; i < 100; ++i) world.Step(1.0f / 60.0f, 8, 3);
  EXPECT_LT(body->GetPosition().y, -1.0f);  // it fell: the world did step
  const b2Profile& p = world.GetProfile();
  EXPECT_EQ(p.step, 0.0f);
  EXPECT_EQ(p.collide, 0.0f);
  EXPECT_EQ(p.solve, 0.0f);
  // Libbox2d's own timer would read at least 2 ms here.
  b2Timer timer;
  std::this_thread::sleep_for(std::chrono::milliseconds(2));
  EXPECT_EQ(timer.GetMilliseconds(), 0.0f);
}
