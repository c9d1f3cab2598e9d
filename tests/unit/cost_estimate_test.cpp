// qdrun --dry-run's cost model (runtime/cost_estimate.hpp) against hand-computed values: a scripted
// environment whose episodes take θ1 steps (truncated) in cell θ0 (truncated), and a representation
// whose "measured" fit time is a known function of the rows it is asked about.
#include "runtime/cost_estimate.hpp"
#include "runtime/run_directory.hpp"

#include <qd/errors.hpp>
#include <qd/planning.hpp>

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <deque>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

using namespace qd;
using namespace qd::runtime;
namespace fs = std::filesystem;

namespace {

constexpr std::int64_t kCells = 50;
constexpr int kMaxSteps = 30;

class StepsEnvironment final : public Environment {
 public:
  EnvironmentInfo info() const override { return {1, 1, kMaxSteps}; }
  void rollout(const RolloutBatch& b, Trace* traces) const override {
    for (std::size_t i = b.begin; i < b.end; ++i) {
      traces[i].main.reset(1);
      traces[i].main.push(b.row(i)[0]);
      traces[i].steps = static_cast<int>(b.row(i)[1]);
    }
  }
};

class CellDescriptor final : public Descriptor {
 public:
  GridSpec grid() const override { return {{kCells}, {"x"}, {0.0}, {double(kCells)}, kCells}; }
  void describe(const Trace* traces, std::size_t n, std::int64_t* cells, double* values) const override {
    for (std::size_t i = 0; i < n; ++i) {
      values[i] = traces[i].main.row(0)[0];
      cells[i] = static_cast<std::int64_t>(values[i]);
    }
  }
};

// Loop 0's rows (θ0, θ1) in order.
class RowsSampler final : public Mutator {
 public:
  explicit RowsSampler(bool parents) : parents_(parents) {}
  bool uses_parents() const noexcept override { return parents_; }
  void mutate(const Parents&, std::size_t count, MutateContext&, Offspring& out) override {
    out.reset(count, 4, 0);
    out.theta.setZero();
    for (std::size_t i = 0; i < count && i < rows.size(); ++i) {
      out.theta(static_cast<Eigen::Index>(i), 0) = rows[i][0];
      out.theta(static_cast<Eigen::Index>(i), 1) = rows[i][1];
    }
  }
  std::vector<std::vector<double>> rows;

 private:
  bool parents_;
};

// A model that says nothing about its fit's cost (no FitTimeEstimate).
class UntimedModel final : public Representation {
 public:
  int latent_size() const noexcept override { return 1; }
  FitReport fit(const Dataset&, const FitContext&) override { return {}; }
  void encode(const Matrix& theta, Matrix& z) const override { z = theta.leftCols(1); }
  void decode(const Matrix& z, Matrix& theta) const override { theta = Matrix::Zero(z.rows(), 4); }
  void decoder_jacobians(const Matrix& z, std::vector<Matrix>& j) const override {
    j.assign(static_cast<std::size_t>(z.rows()), Matrix::Zero(4, 1));
  }
  void save(std::ostream&) const override {}
  void load(std::istream&) override {}
};

// A model whose fit "takes" half a second per row; or one that breaks the contract.
class TimedModel final : public Representation, public FitTimeEstimate {
 public:
  enum class Fault { kNone, kWrongSize, kNan, kThrows };
  explicit TimedModel(int latent, Fault fault = Fault::kNone) : latent_(latent), fault_(fault) {}
  int latent_size() const noexcept override { return latent_; }
  FitReport fit(const Dataset&, const FitContext&) override { return {}; }
  void encode(const Matrix& theta, Matrix& z) const override { z = theta.leftCols(latent_); }
  void decode(const Matrix& z, Matrix& theta) const override { theta = Matrix::Zero(z.rows(), 4); }
  void decoder_jacobians(const Matrix& z, std::vector<Matrix>& j) const override {
    j.assign(static_cast<std::size_t>(z.rows()), Matrix::Zero(4, latent_));
  }
  std::vector<double> estimate_fit_seconds(const std::vector<std::size_t>& rows) const override {
    asked.push_back(rows);
    std::vector<double> s;
    for (std::size_t r : rows) s.push_back(0.5 * static_cast<double>(r));
    if (fault_ == Fault::kWrongSize) s.pop_back();
    if (fault_ == Fault::kNan) s.back() = std::nan("");
    if (fault_ == Fault::kThrows) throw std::runtime_error("no clock");
    return s;
  }
  void save(std::ostream&) const override {}
  void load(std::istream&) override {}
  mutable std::vector<std::vector<std::size_t>> asked;

 private:
  int latent_;
  Fault fault_;
};

template <class T, class... A>
Owned<T> own(A&&... a) {
  return Owned<T>(new T(std::forward<A>(a)...), LibraryHoldingDeleter{});
}

struct World {
  World(bool parents, int latent, TimedModel::Fault fault = TimedModel::Fault::kNone) {
    s.seed = 3;
    s.loops = 3;
    s.iterations = 2;
    s.batch = 5;
    s.initial_samples = 6;
    s.insertion = InsertionRule::kCoinFlip;
    s.dataset_order = DatasetOrder::kReference;
    c.shape = PolicyShape(1, {1}, 1);
    c.environment = own<StepsEnvironment>();
    c.descriptor = own<CellDescriptor>();
    c.grid = c.descriptor->grid();
    auto m = own<TimedModel>(latent, fault);
    model = m.get();
    c.representation = std::move(m);
    c.representation_label = "representation 'timed' (test)";
    auto sampler = own<RowsSampler>(false);
    // The first policy to reach a cell is its elite: each of cells 1, 2, 3 gets a 6-step one.
    sampler->rows = {{1, 6}, {1, 4}, {2, 6}, {3, 6}, {3, 10}, {3, 12}};
    c.initial = std::move(sampler);
    c.mutator = own<RowsSampler>(parents);
  }
  ExperimentSettings s;
  CostModel cost;  // [cost]: none unless a test sets it
  Components c;
  TimedModel* model = nullptr;
};

// A pilot of known numbers: 100 loop-0 episodes in 2 s (20 ms each), 50 offspring in 3 s (60 ms
// each), 6 cells after loop 0.
EpisodePilot known_pilot() {
  EpisodePilot p;
  p.episodes = 100;
  p.seconds = 2.0;
  p.mean_steps = 10;
  p.max_steps = kMaxSteps;
  p.loop0_archive = 6;
  p.offspring_episodes = 50;
  p.offspring_seconds = 3.0;
  p.offspring_mean_steps = 25;
  return p;
}

TEST(CostEstimate, PilotRunsLoopZeroAndCountsStepsAndCells) {
  World w(true, 0);
  const EpisodePilot p = run_episode_pilot(w.s, w.c);
  EXPECT_EQ(p.episodes, 6u);
  EXPECT_DOUBLE_EQ(p.mean_steps, 44.0 / 6);  // (6 + 4 + 6 + 6 + 10 + 12) / 6
  EXPECT_EQ(p.max_steps, kMaxSteps);
  EXPECT_EQ(p.loop0_archive, 3u);  // cells 1, 2, 3
  EXPECT_GE(p.seconds, 0.0);
}

TEST(CostEstimate, PilotOffspringAreTheElitesBredOnce) {
  World w(true, 0);
  // Without a step, every offspring is a copy of an elite: 6 steps each, whichever were drawn.
  const EpisodePilot copies = run_episode_pilot(w.s, w.c, 0.0);
  EXPECT_EQ(copies.offspring_episodes, 6u);  // as many as loop 0's samples
  EXPECT_DOUBLE_EQ(copies.offspring_mean_steps, 6.0);
  EXPECT_GE(copies.offspring_seconds, 0.0);
  // With the default step, theta1 = 6 + 0.1 N(0, 1) truncates to 5 for every negative draw.
  const EpisodePilot bred = run_episode_pilot(w.s, w.c);
  EXPECT_EQ(bred.offspring_episodes, 6u);
  EXPECT_GE(bred.offspring_mean_steps, 5.0);
  EXPECT_LT(bred.offspring_mean_steps, 6.0);  // seed 3 draws at least one negative
}

TEST(CostEstimate, MutationEpisodesCostWhatThePilotsOffspringCost) {
  World w(true, 0);
  const CostEstimate e = estimate_run_cost(w.s, w.cost, w.c, known_pilot());
  EXPECT_EQ(e.evaluations, 6 + 2 * 2 * 5);
  EXPECT_DOUBLE_EQ(e.episode_seconds, 6 * 0.020 + 20 * 0.060);
  EXPECT_EQ(e.training_seconds, 0.0);  // no latent space: the model is not asked
  EXPECT_TRUE(w.model->asked.empty());
}

TEST(CostEstimate, SamplerEpisodesCostWhatLoopZerosCost) {
  World w(false, 0);
  const CostEstimate e = estimate_run_cost(w.s, w.cost, w.c, known_pilot());
  EXPECT_DOUBLE_EQ(e.episode_seconds, 26 * 0.020);
}

TEST(CostEstimate, WithoutElitesOffspringArePricedAsLoopZero) {
  EpisodePilot p = known_pilot();
  p.offspring_episodes = 0;
  p.offspring_seconds = 0.0;
  World w(true, 0);
  EXPECT_DOUBLE_EQ(p.offspring_seconds_per_episode(), 0.020);
  EXPECT_DOUBLE_EQ(estimate_run_cost(w.s, w.cost, w.c, p).episode_seconds, 26 * 0.020);
}

TEST(CostEstimate, TrainingAddsTheModelsTimeForTheExpectedDatasetSizes) {
  World w(true, 1);
  const CostEstimate e = estimate_run_cost(w.s, w.cost, w.c, known_pilot());
  // |D| = 6 after loop 0, then 6 (1 + kDatasetGrowth sqrt(loop)).
  const std::vector<std::size_t> rows = {6, static_cast<std::size_t>(6 * (1 + kDatasetGrowth)),
                                         static_cast<std::size_t>(6 * (1 + kDatasetGrowth * std::sqrt(2.0)))};
  ASSERT_EQ(w.model->asked.size(), 1u);
  EXPECT_EQ(w.model->asked[0], rows);
  EXPECT_DOUBLE_EQ(e.training_seconds, 0.5 * static_cast<double>(rows[0] + rows[1] + rows[2]));
}

TEST(CostEstimate, DatasetNeverOutgrowsTheGrid) {
  EpisodePilot p = known_pilot();
  p.loop0_archive = 40;
  World w(true, 1);
  EXPECT_EQ(expected_dataset_rows(w.s, w.cost, p, kCells, 0), 40u);
  EXPECT_EQ(expected_dataset_rows(w.s, w.cost, p, kCells, 100), static_cast<std::size_t>(kCells));
  w.cost.evaluations = {0, 10};
  w.cost.cells = {0, 1e6};
  EXPECT_EQ(expected_dataset_rows(w.s, w.cost, p, kCells, 1), static_cast<std::size_t>(kCells));
}

// World: loop 0 is 6 evaluations, loops 1 and 2 are 10 each, so they end at 16 and 26.
TEST(CostEstimate, TheCostTablesCellsSizeEachFitAtItsLoopsEnd) {
  World w(true, 1);
  EXPECT_DOUBLE_EQ(loop_end_evaluations(w.s, 0), 6.0);
  EXPECT_DOUBLE_EQ(loop_end_evaluations(w.s, 2), 26.0);
  w.cost.evaluations = {0, 16, 36};
  w.cost.cells = {0, 20, 40};
  const CostEstimate e = estimate_run_cost(w.s, w.cost, w.c, known_pilot());
  // Loop 0's fit sees the pilot's archive (6); loop 1's the 20 cells found by evaluation 16; loop
  // 2's 20 + (26 - 16) / (36 - 16) x 20 = 30.
  ASSERT_EQ(w.model->asked.size(), 1u);
  EXPECT_EQ(w.model->asked[0], (std::vector<std::size_t>{6, 20, 30}));
  EXPECT_DOUBLE_EQ(e.training_seconds, 0.5 * (6 + 20 + 30));
  EXPECT_EQ(e.dataset_rows_last, 30u);
  EXPECT_TRUE(e.dataset_rows_from_cost);
  // Cells alone do not lengthen episodes: the pilot's offspring price loops 1 and 2.
  EXPECT_DOUBLE_EQ(e.episode_seconds, 6 * 0.020 + 20 * 0.060);
  // Never below what loop 0 found.
  w.cost.cells = {0, 1, 2};
  EXPECT_EQ(expected_dataset_rows(w.s, w.cost, known_pilot(), kCells, 2), 6u);
}

TEST(CostEstimate, AResumedRunCountsOnlyTheLoopsLeft) {
  World w(true, 1);
  const CostEstimate e = estimate_run_cost(w.s, w.cost, w.c, known_pilot(), 2);
  EXPECT_EQ(e.evaluations, 10);
  EXPECT_DOUBLE_EQ(e.episode_seconds, 10 * 0.060);
  EXPECT_DOUBLE_EQ(e.training_seconds,
                   0.5 * static_cast<double>(expected_dataset_rows(w.s, w.cost, known_pilot(), kCells, 2)));
}

TEST(CostEstimate, AResumedRunsOwnRatePricesItsEvaluationsInsteadOfThePilot) {
  World w(true, 1);
  const CostEstimate e = estimate_run_cost(w.s, w.cost, w.c, known_pilot(), 2, {0.5, 1});
  EXPECT_EQ(e.evaluations, 10);
  EXPECT_DOUBLE_EQ(e.episode_seconds, 10 * 0.5);
  EXPECT_DOUBLE_EQ(e.training_seconds,
                   0.5 * static_cast<double>(expected_dataset_rows(w.s, w.cost, known_pilot(), kCells, 2)));
}

TEST(CostEstimate, ARepresentationWithoutFitTimeEstimateAddsNoTraining) {
  World w(true, 1);
  w.c.representation = own<UntimedModel>();
  const CostEstimate e = estimate_run_cost(w.s, w.cost, w.c, known_pilot());
  EXPECT_EQ(e.training_seconds, 0.0);
  EXPECT_DOUBLE_EQ(e.episode_seconds, 6 * 0.020 + 20 * 0.060);  // the episodes are priced as ever
}

TEST(CostEstimate, TheCostTableInterpolatesLinearlyAndHoldsItsEnds) {
  CostModel m;
  EXPECT_EQ(m.offspring_time_at(123.0), 1.0);  // no table: the pilot's offspring throughout
  m.evaluations = {10, 30};
  m.offspring_time = {2, 4};
  EXPECT_DOUBLE_EQ(m.offspring_time_at(0), 2.0);
  EXPECT_DOUBLE_EQ(m.offspring_time_at(10), 2.0);
  EXPECT_DOUBLE_EQ(m.offspring_time_at(11), 2.1);
  EXPECT_DOUBLE_EQ(m.offspring_time_at(20), 3.0);
  EXPECT_DOUBLE_EQ(m.offspring_time_at(30), 4.0);
  EXPECT_DOUBLE_EQ(m.offspring_time_at(1e9), 4.0);
}

// World: loop 0 is 6 evaluations, loops 1 and 2 are 10 each, so their middles are at 11 and 21.
TEST(CostEstimate, TheCostTablePricesABreedingRunsEpisodesFromLoopZerosAtEachLoopsMiddle) {
  World w(true, 0);
  EXPECT_DOUBLE_EQ(loop_midpoint_evaluations(w.s, 1), 11.0);
  EXPECT_DOUBLE_EQ(loop_midpoint_evaluations(w.s, 2), 21.0);
  w.cost.evaluations = {10, 30};
  w.cost.offspring_time = {2, 4};
  const CostEstimate e = estimate_run_cost(w.s, w.cost, w.c, known_pilot());
  // Measured on long runs against loop 0's time, so it replaces the pilot's offspring.
  EXPECT_DOUBLE_EQ(e.episode_seconds, 6 * 0.020 + 10 * 0.020 * 2.1 + 10 * 0.020 * 3.1);

  World sampler(false, 0);  // random search does not breed from elites: loop 0's time throughout
  sampler.cost = w.cost;
  EXPECT_DOUBLE_EQ(estimate_run_cost(sampler.s, sampler.cost, sampler.c, known_pilot()).episode_seconds, 26 * 0.020);
}

TEST(CostEstimate, AResumedRunsOwnRateGrowsAsTheCostTableDoesFromItsMeasuredLoop) {
  World w(true, 0);
  w.cost.evaluations = {10, 30};
  w.cost.offspring_time = {2, 4};
  // Measured in loop 1 (factor 2.1): loop 2 (factor 3.1) costs 3.1 / 2.1 of it.
  EXPECT_DOUBLE_EQ(estimate_run_cost(w.s, w.cost, w.c, known_pilot(), 2, {0.5, 1}).episode_seconds,
                   10 * 0.5 * 3.1 / 2.1);
  World sampler(false, 0);
  sampler.cost = w.cost;
  EXPECT_DOUBLE_EQ(estimate_run_cost(sampler.s, sampler.cost, sampler.c, known_pilot(), 2, {0.5, 1}).episode_seconds,
                   10 * 0.5);
}

TEST(CostEstimate, TheMeasuredLoopsWorkersComeFromTheSessionThatRanIt) {
  const fs::path dir = fs::temp_directory_path() / ("qd-session-provenance-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  for (const char* name : {"provenance.toml", "provenance-resume-loop-3.toml", "provenance-resume-loop-12.toml"})
    std::ofstream(dir / name) << "workers = 1\n";
  EXPECT_EQ(session_provenance(dir, 2).filename(), "provenance.toml");
  EXPECT_EQ(session_provenance(dir, 3).filename(), "provenance-resume-loop-3.toml");
  EXPECT_EQ(session_provenance(dir, 11).filename(), "provenance-resume-loop-3.toml");
  EXPECT_EQ(session_provenance(dir, 1 << 30).filename(), "provenance-resume-loop-12.toml");
  fs::remove_all(dir);
}

TEST(CostEstimate, AModelsBrokenEstimateEndsTheDryRunNamingIt) {
  for (auto fault : {TimedModel::Fault::kWrongSize, TimedModel::Fault::kNan, TimedModel::Fault::kThrows}) {
    World w(true, 1, fault);
    try {
      estimate_run_cost(w.s, w.cost, w.c, known_pilot());
      ADD_FAILURE() << "no error for fault " << static_cast<int>(fault);
    } catch (const PluginError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("representation 'timed' (test)"), std::string::npos) << what;
      EXPECT_NE(what.find("estimate_fit_seconds()"), std::string::npos) << what;
    }
  }
}

}  // namespace

namespace {

// metrics.csv as run.cpp writes it: cumulative wall and training seconds per iteration row.
constexpr const char* kMetricsHeader =
    "loop,iteration,evaluations,elites,coverage,mixing_ratio,added,replaced,invalid,wall_seconds,train_seconds\n";

std::string metrics_row(int loop, int it, int evaluations, double wall, double train) {
  return std::to_string(loop) + "," + std::to_string(it) + "," + std::to_string(evaluations) + ",1,0.1,,1,0,0," +
         std::to_string(wall) + "," + std::to_string(train) + "\n";
}

TEST(CostEstimate, AResumedRunIsPricedAtItsLastCompleteLoopsMedianRate) {
  std::string csv = kMetricsHeader;
  csv += metrics_row(0, 0, 10, 1.0, 0.0);
  // Loop 1: 0.1 s per evaluation (the first row also carries loop 0's 10 s fit).
  csv += metrics_row(1, 0, 20, 12.0, 10.0);
  csv += metrics_row(1, 1, 30, 13.0, 10.0);
  csv += metrics_row(1, 2, 40, 14.0, 10.0);
  // Loop 2: 0.2, then a 5 s pause, then 0.2 s per evaluation; its median is 0.2.
  csv += metrics_row(2, 0, 50, 26.0, 20.0);
  csv += metrics_row(2, 1, 60, 31.0, 20.0);
  csv += metrics_row(2, 2, 70, 33.0, 20.0);
  // Loop 3 stopped after one iteration: not complete, not used.
  csv += metrics_row(3, 0, 80, 53.0, 30.0);
  std::istringstream in(csv);
  const MeasuredRate rate = measured_rate(in, 3);
  EXPECT_EQ(rate.loop, 2);
  EXPECT_NEAR(rate.seconds_per_evaluation, 0.2, 1e-12);
}

TEST(CostEstimate, WithoutACompleteLoopPastZeroThereIsNoMeasuredRate) {
  std::string csv = kMetricsHeader;
  csv += metrics_row(0, 0, 10, 1.0, 0.0);
  csv += metrics_row(1, 0, 20, 12.0, 10.0);
  std::istringstream in(csv);
  EXPECT_EQ(measured_rate(in, 3).loop, -1);
  EXPECT_EQ(measured_rate(in, 3).seconds_per_evaluation, 0.0);
  std::istringstream other("loop,iteration,evaluations\n0,0,10\n1,0,20\n1,1,30\n");  // no times
  EXPECT_EQ(measured_rate(other, 2).loop, -1);
  std::istringstream empty("");
  EXPECT_EQ(measured_rate(empty, 2).loop, -1);
}

}  // namespace
