// The MAP-Elites loop against its rules, with a scripted world whose answers are known: the
// environment reads a policy's first parameter as its cell and its second as its fitness, a
// scripted mutator returns exactly the offspring a test asks for (and records the parents it is
// given), and a linear representation has a known reconstruction error. Each test states the rule
// of the paper it checks; tests/README.md lists the deliberate bugs each one catches.
#include "runtime/map_elites.hpp"
#include "runtime/thread_evaluator.hpp"

#include <qd/rng.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <deque>
#include <map>
#include <set>
#include <vector>

using namespace qd;
using namespace qd::runtime;

namespace {

constexpr std::int64_t kCells = 50;
constexpr int kP = 4;  // PolicyShape(1, {1}, 1)
// θ3 breaks a plugin's contract on purpose (issue 20): the environment returns a NaN fitness, the
// descriptor an infinite value or a cell outside the grid.
constexpr double kNanFitness = 7, kInfDescriptor = 8, kCellOutOfRange = 9;

// trace.main = (θ0, θ1, θ3); fitness θ1; a negative θ0 is a failed episode.
class ScriptedEnvironment final : public Environment {
 public:
  EnvironmentInfo info() const override { return {1, 1, 1}; }
  void rollout(const RolloutBatch& b, Trace* traces) const override {
    for (std::size_t i = b.begin; i < b.end; ++i) {
      const double* theta = b.row(i);
      Trace& t = traces[i];
      t.main.reset(3);
      t.main.push(theta[0], theta[1], theta[3]);
      t.fitness = theta[3] == kNanFitness ? std::nan("") : theta[1];
      t.steps = 1;
      t.status = theta[0] < 0 ? EvalStatus::kFailed : EvalStatus::kOk;
    }
  }
};

// Cell = θ0 rounded down; θ0 >= kCells cannot be described (cell -1).
class ScriptedDescriptor final : public Descriptor {
 public:
  GridSpec grid() const override { return {{kCells}, {"x"}, {0.0}, {double(kCells)}, kCells}; }
  void describe(const Trace* traces, std::size_t n, std::int64_t* cells, double* values) const override {
    for (std::size_t i = 0; i < n; ++i) {
      const double x = traces[i].main.row(0)[0], fault = traces[i].main.row(0)[2];
      cells[i] = x < double(kCells) ? static_cast<std::int64_t>(std::floor(x)) : -1;
      values[i] = fault == kInfDescriptor ? INFINITY : x;
      if (fault == kCellOutOfRange) cells[i] = kCells;
    }
  }
};

// Returns the rows queued by the test, in order; records the parents of every call and the
// feedback it gets. As the initial sampler it takes no parents.
class ScriptedMutator final : public Mutator {
 public:
  explicit ScriptedMutator(bool parents) : parents_(parents) {}
  bool uses_parents() const noexcept override { return parents_; }
  std::vector<std::string> metric_names() const override { return {kMixingRatio}; }
  void mutate(const Parents& parents, std::size_t count, MutateContext&, Offspring& out) override {
    seen_parents.push_back(parents.cells);
    out.reset(count, kP, latent_size);
    for (std::size_t i = 0; i < count; ++i) {
      EXPECT_FALSE(queue.empty()) << "the test queued too few offspring";
      if (queue.empty()) break;
      const std::vector<double> row = queue.front();
      queue.pop_front();
      for (int k = 0; k < kP; ++k) out.theta(static_cast<Eigen::Index>(i), k) = row[static_cast<std::size_t>(k)];
      if (latent_origin && latent_size > 0) {  // a latent-space offspring: θ′ = Dec(z′), z′ = θ′ row head
        out.latent(static_cast<Eigen::Index>(i), 0) = row[0];
        out.has_latent[i] = 1;
      }
    }
    out.metrics = {0.25};  // the mixing ratio
  }
  void feedback(const Feedback& fb) override {
    feedbacks.push_back(fb);
    results.push_back(*fb.results);  // the loop reuses its vector
  }

  std::deque<std::vector<double>> queue;
  std::vector<std::vector<std::int64_t>> seen_parents;
  std::vector<Feedback> feedbacks;
  std::vector<std::vector<OffspringResult>> results;
  std::size_t latent_size = 0;
  bool latent_origin = false;

 private:
  bool parents_;
};

// Enc(θ) = θ0 (one latent dimension), Dec(z) = (z, 0, 0, 0): ‖θ − Dec(Enc θ)‖ = ‖(θ1, θ2, θ3)‖.
class FirstCoordinate final : public Representation {
 public:
  int latent_size() const noexcept override { return 1; }
  FitReport fit(const Dataset& data, const FitContext& ctx) override {
    fitted_sizes.push_back(data.size());
    fitted_loops.push_back(ctx.loop);
    return {1, 0.0, 0.0, false};
  }
  void encode(const Matrix& theta, Matrix& z) const override { z = theta.leftCols(1); }
  void decode(const Matrix& z, Matrix& theta) const override {
    theta = Matrix::Zero(z.rows(), kP);
    theta.col(0) = z.col(0);
    if (nan_decode) theta(0, 0) = NAN;
  }
  void decoder_jacobians(const Matrix& z, std::vector<Matrix>& j) const override {
    j.assign(static_cast<std::size_t>(z.rows()), Matrix::Zero(kP, 1));
    for (auto& m : j) m(0, 0) = 1.0;
  }
  void save(std::ostream&) const override {}
  void load(std::istream&) override {}
  std::vector<std::size_t> fitted_sizes;
  std::vector<int> fitted_loops;
  bool nan_decode = false;  // a broken decoder (issue 20)
};

class NoModel final : public Representation {
 public:
  int latent_size() const noexcept override { return 0; }
  FitReport fit(const Dataset&, const FitContext&) override { return {}; }
  void encode(const Matrix&, Matrix&) const override {}
  void decode(const Matrix&, Matrix&) const override {}
  void decoder_jacobians(const Matrix&, std::vector<Matrix>&) const override {}
  void save(std::ostream&) const override {}
  void load(std::istream&) override {}
};

class Recorder final : public LoopObserver {
 public:
  void iteration_done(const IterationOutcome& o) override {
    outcomes.push_back(o);
    mixing.push_back(o.offspring->metrics.at(0));
  }
  void training_done(int loop, const FitReport&, double) override { trained.push_back(loop); }
  std::vector<IterationOutcome> outcomes;
  std::vector<double> mixing;
  std::vector<int> trained;
};

template <class T, class... A>
Owned<T> own(A&&... a) {
  return Owned<T>(new T(std::forward<A>(a)...), LibraryHoldingDeleter{});
}

// One loop's world: components, evaluator, archive, dataset, and the loop itself.
struct World {
  explicit World(bool with_model = false, int batch = 4, int initial_samples = 6) {
    s.seed = 11;
    s.loops = 3;
    s.iterations = 2;
    s.batch = batch;
    s.initial_samples = initial_samples;
    s.insertion = InsertionRule::kCoinFlip;
    s.replace_probability = 0.5;
    s.dataset_order = DatasetOrder::kReference;
    c.shape = PolicyShape(1, {1}, 1);  // 4 parameters; only the first three are read
    c.environment = own<ScriptedEnvironment>();
    c.descriptor = own<ScriptedDescriptor>();
    c.grid = c.descriptor->grid();
    if (with_model) {
      auto m = own<FirstCoordinate>();
      model = m.get();
      c.representation = std::move(m);
    } else {
      c.representation = own<NoModel>();
    }
    auto m = own<ScriptedMutator>(true), i = own<ScriptedMutator>(false);
    mutator = m.get();
    initial = i.get();
    mutator->latent_size = with_model ? 1 : 0;
    c.metric_names = m->metric_names();
    c.mutator = std::move(m);
    c.initial = std::move(i);
    evaluator = std::make_unique<ThreadEvaluator>(*c.environment, *c.descriptor, c.shape, 1);
    archive = std::make_unique<Archive>(kCells, c.shape.param_count(), 1);
    dataset = std::make_unique<Dataset>(c.shape.param_count());
    loop = std::make_unique<MapElites>(s, c, *evaluator, *archive, *dataset, recorder);
  }
  // Queues rows (θ0, θ1, θ2) for the initial sampler or the mutator.
  static void queue(ScriptedMutator& m, const std::vector<std::vector<double>>& rows) {
    for (auto r : rows) {
      r.resize(kP, 0.0);
      m.queue.push_back(r);
    }
  }
  double param(std::int64_t cell, int k) const {
    return archive->params(static_cast<std::size_t>(archive->slot_of(cell)))[k];
  }

  ExperimentSettings s;
  Components c;
  ScriptedMutator* mutator = nullptr;
  ScriptedMutator* initial = nullptr;
  FirstCoordinate* model = nullptr;
  Recorder recorder;
  std::unique_ptr<Evaluator> evaluator;
  std::unique_ptr<Archive> archive;
  std::unique_ptr<Dataset> dataset;
  std::unique_ptr<MapElites> loop;
};

// The coin draws of one iteration, in order: uniform() < p replaces.
std::vector<bool> coins(const ExperimentSettings& s, int loop, int it, std::size_t n) {
  Rng coin(s.seed, Stream::kInsertion, static_cast<std::uint64_t>(loop), static_cast<std::uint64_t>(it));
  std::vector<bool> out;
  for (std::size_t k = 0; k < n; ++k) out.push_back(coin.uniform() < s.replace_probability);
  return out;
}

}  // namespace

// Loop 0: the archive holds the first sampled policy of each distinct cell; undescribable and
// failed samples are counted invalid; D is the archive, ordered by descending cell (reference).
TEST(MapElitesLoop, LoopZeroKeepsTheFirstPolicyOfEachCell) {
  World w;
  World::queue(*w.initial, {{3.5, 1}, {7.2, 2}, {3.9, 3}, {-1, 0}, {60, 0}, {1.0, 4}});
  w.loop->run_loop(0);
  EXPECT_EQ(w.archive->size(), 3u);
  EXPECT_EQ(w.param(3, 1), 1.0) << "the first sample of cell 3, not the later one";
  EXPECT_EQ(w.param(7, 1), 2.0);
  EXPECT_EQ(w.param(1, 1), 4.0);
  ASSERT_EQ(w.recorder.outcomes.size(), 1u);
  EXPECT_EQ(w.recorder.outcomes[0].added, 3u);
  EXPECT_EQ(w.recorder.outcomes[0].invalid, 2u);
  EXPECT_EQ(w.recorder.outcomes[0].replaced, 0u);
  EXPECT_EQ(w.dataset->cells(), (std::vector<std::int64_t>{7, 3, 1}));
  EXPECT_EQ(w.loop->evaluations(), 6u);
}

// An offspring fills an empty cell; an occupied cell is replaced exactly when the iteration's
// coin (drawn only for occupied cells, in offspring order) says so.
TEST(MapElitesLoop, CoinFlipDecidesOnlyOccupiedCells) {
  World w(false, 8);
  World::queue(*w.initial, {{1, 0}, {2, 0}, {3, 0}, {4, 0}, {5, 0}, {6, 0}});
  w.loop->run_loop(0);
  // Iteration 0: four occupied cells, an empty one, occupied again, two new ones.
  World::queue(*w.mutator, {{1, 10}, {2, 11}, {9, 12}, {3, 13}, {4, 14}, {2, 15}, {10, 16}, {5, 17}});
  World::queue(*w.mutator, std::vector<std::vector<double>>(8, {20, 1}));  // iteration 1: one cell
  w.loop->run_loop(1);
  const std::vector<bool> c0 = coins(w.s, 1, 0, 6);
  // Occupied in offspring order: cells 1, 2, 3, 4, 2, 5 -> coins 0..5.
  const std::map<std::int64_t, double> expected = {{1, c0[0] ? 10 : 0},
                                                   {2, c0[4] ? 15 : (c0[1] ? 11 : 0)},
                                                   {3, c0[2] ? 13 : 0},
                                                   {4, c0[3] ? 14 : 0},
                                                   {5, c0[5] ? 17 : 0},
                                                   {9, 12},
                                                   {10, 16},
                                                   {6, 0}};
  const std::vector<bool> c1 = coins(w.s, 1, 1, 7);  // cell 20: added, then 7 coin draws
  double cell20 = 1;  // every offspring of iteration 1 is (20, 1): whatever wins, θ1 = 1
  for (const auto& [cell, fitness] : expected) EXPECT_EQ(w.param(cell, 1), fitness) << "cell " << cell;
  EXPECT_EQ(w.param(20, 1), cell20);
  const std::size_t replaced0 = std::size_t(std::count(c0.begin(), c0.end(), true));
  ASSERT_EQ(w.recorder.outcomes.size(), 3u);
  EXPECT_EQ(w.recorder.outcomes[1].added, 2u);
  EXPECT_EQ(w.recorder.outcomes[1].replaced, replaced0);
  EXPECT_EQ(w.recorder.outcomes[1].rejected, 6u - replaced0);
  EXPECT_EQ(w.recorder.outcomes[2].added, 1u);
  EXPECT_EQ(w.recorder.outcomes[2].replaced, std::size_t(std::count(c1.begin(), c1.end(), true)));
  // The mutator heard the same, with one outcome per offspring.
  ASSERT_EQ(w.mutator->feedbacks.size(), 2u);
  EXPECT_EQ(w.mutator->feedbacks[0].replaced, replaced0);
  EXPECT_EQ(w.mutator->results[0].size(), 8u);
}

// The mutator hears, per offspring in batch order, what became of it and the fitness change it
// brought to its cell (what CMA-ME's emitters rank by): a new cell (change = its fitness), an
// improvement and a discarded offer (change against the occupant just before it, so two offers to
// one cell in one batch see each other), an invalid evaluation; and, under the coin flip, a
// replacement that is no improvement.
TEST(MapElitesLoop, FeedbackTellsEachOffspringsOutcomeAndFitnessChange) {
  World w(false, 5, 2);
  w.s.insertion = InsertionRule::kFitness;
  World::queue(*w.initial, {{1, 5}, {2, 5}});
  w.loop->run_loop(0);
  World::queue(*w.mutator, {{1, 4}, {1, 6}, {1, 5.5}, {3, 2}, {-1, 9}});
  World::queue(*w.mutator, std::vector<std::vector<double>>(5, {-1, 0}));
  w.loop->run_loop(1);
  ASSERT_EQ(w.mutator->results.size(), 2u);
  const std::vector<OffspringResult>& r = w.mutator->results[0];
  ASSERT_EQ(r.size(), 5u);
  const std::vector<Outcome> outcomes = {Outcome::kDiscarded, Outcome::kImproved, Outcome::kDiscarded,
                                         Outcome::kNewCell, Outcome::kInvalid};
  const std::vector<double> changes = {-1.0, 1.0, -0.5, 2.0};
  const std::vector<std::int64_t> cells = {1, 1, 1, 3, -1};
  for (std::size_t k = 0; k < r.size(); ++k) {
    EXPECT_EQ(r[k].outcome, outcomes[k]) << "offspring " << k << ": " << to_string(r[k].outcome);
    EXPECT_EQ(r[k].cell, cells[k]) << k;
    if (k < changes.size()) {
      EXPECT_EQ(r[k].change(), changes[k]) << k;
    }
  }
  EXPECT_EQ(r[1].previous, 5.0);
  EXPECT_EQ(r[2].previous, 6.0) << "the second offer to cell 1 meets the first one's improvement";
  EXPECT_TRUE(std::isnan(r[3].previous));
  EXPECT_TRUE(std::isnan(r[4].fitness) && std::isnan(r[4].change()));
  EXPECT_TRUE(r[1].entered() && r[3].entered() && !r[0].entered() && !r[4].entered());

  World c(false, 2, 1);
  c.s.replace_probability = 1.0;  // every occupied offer replaces, improving or not
  World::queue(*c.initial, {{1, 5}});
  c.loop->run_loop(0);
  World::queue(*c.mutator, {{1, 3}, {1, 4}});
  World::queue(*c.mutator, {{1, 3}, {1, 3}});
  c.loop->run_loop(1);
  EXPECT_EQ(c.mutator->results[0][0].outcome, Outcome::kReplaced);
  EXPECT_EQ(c.mutator->results[0][0].change(), -2.0);
  EXPECT_EQ(c.mutator->results[0][1].outcome, Outcome::kImproved);
  EXPECT_EQ(c.mutator->results[1][1].outcome, Outcome::kReplaced) << "equal fitness is no improvement";
  EXPECT_EQ(c.mutator->feedbacks[0].replaced, 2u);
}

// Over many occupied-cell offers the replacement rate is the configured probability (0.5):
// 2000 offers, binomial standard deviation 22, bounds at 5 of them.
TEST(MapElitesLoop, CoinFlipReplacesHalfTheOccupiedOffers) {
  World w(false, 400, 1);
  w.s.iterations = 5;
  World::queue(*w.initial, {{4, 0}});
  w.loop->run_loop(0);
  World::queue(*w.mutator, std::vector<std::vector<double>>(2000, {4, 1}));
  w.loop->run_loop(1);
  std::size_t replaced = 0;
  for (std::size_t k = 1; k < w.recorder.outcomes.size(); ++k) replaced += w.recorder.outcomes[k].replaced;
  EXPECT_GT(replaced, 1000u - 110u);
  EXPECT_LT(replaced, 1000u + 110u);
}

// insertion = "fitness": an occupant is replaced exactly when the offspring's fitness is higher
// (ties keep the occupant); no coin is involved.
TEST(MapElitesLoop, FitnessInsertionReplacesOnlyStrictlyBetter) {
  World w(false, 4, 2);
  w.s.insertion = InsertionRule::kFitness;
  World::queue(*w.initial, {{1, 5}, {2, 5}});
  w.loop->run_loop(0);
  World::queue(*w.mutator, {{1, 4}, {1, 5}, {2, 7}, {2, 6}});
  World::queue(*w.mutator, {{1, 5.5}, {2, 7}, {1, 5.25}, {3, -100}});
  w.loop->run_loop(1);
  EXPECT_EQ(w.param(1, 1), 5.5);
  EXPECT_EQ(w.param(2, 1), 7.0);
  EXPECT_EQ(w.archive->fitness(static_cast<std::size_t>(w.archive->slot_of(3))), -100.0);
  EXPECT_EQ(w.recorder.outcomes[1].replaced, 1u);  // (2, 7) only
  EXPECT_EQ(w.recorder.outcomes[2].replaced, 1u);  // (1, 5.5) only
}

// D gains exactly the cells first filled in the loop, each with its occupant at the loop's end
// (a replacement later in the same loop is what D keeps), in the order they were found; cells
// that were only replaced add nothing.
TEST(MapElitesLoop, DatasetGrowsByTheNewCellsWithTheirFinalOccupants) {
  World w(false, 3, 2);
  w.s.replace_probability = 1.0;  // every occupied offer replaces
  World::queue(*w.initial, {{1, 0}, {2, 0}});
  w.loop->run_loop(0);
  EXPECT_EQ(w.dataset->size(), 2u);
  World::queue(*w.mutator, {{8, 1}, {1, 2}, {5, 3}});   // new 8, replace 1, new 5
  World::queue(*w.mutator, {{8, 4}, {-1, 0}, {9, 5}});  // replace 8, invalid, new 9
  w.loop->run_loop(1);
  EXPECT_EQ(w.dataset->cells(), (std::vector<std::int64_t>{2, 1, 8, 5, 9}));
  EXPECT_EQ(w.dataset->params()(2, 1), 4.0) << "cell 8's occupant at the end of the loop";
  EXPECT_EQ(w.dataset->params()(1, 1), 0.0) << "cell 1 was in D before: its entry stays as it was";
  EXPECT_EQ(w.dataset->loops(), (std::vector<int>{0, 0, 1, 1, 1}));
}

// Selection is uniform over the elites, without replacement once the archive holds at least a
// batch, with replacement before that; parents are always elites.
TEST(MapElitesLoop, SelectionWithoutReplacementOnceTheArchiveHoldsABatch) {
  World w(false, 20, 20);
  std::vector<std::vector<double>> twenty;
  for (int c = 0; c < 20; ++c) twenty.push_back({double(c), 0});
  World::queue(*w.initial, twenty);
  w.loop->run_loop(0);
  World::queue(*w.mutator, std::vector<std::vector<double>>(40, {30, 0}));
  w.loop->run_loop(1);
  for (const auto& parents : w.mutator->seen_parents) {
    ASSERT_EQ(parents.size(), 20u);
    EXPECT_EQ(std::set<std::int64_t>(parents.begin(), parents.end()).size(), 20u) << "a parent drawn twice";
  }

  World small(false, 20, 3);
  World::queue(*small.initial, {{1, 0}, {2, 0}, {3, 0}});
  small.loop->run_loop(0);
  World::queue(*small.mutator, std::vector<std::vector<double>>(40, {-1, 0}));
  small.loop->run_loop(1);
  for (const auto& parents : small.mutator->seen_parents) {
    ASSERT_EQ(parents.size(), 20u);
    for (std::int64_t cell : parents) EXPECT_TRUE(cell >= 1 && cell <= 3) << cell;
  }
}

// With a latent model: elites from loop 0 get the loop-0 model's errors after its fit; an
// offspring made in parameter space stores ‖θ′ − Dec(Enc θ′)‖; one made in latent space
// (θ′ = Dec(z′)) stores 0; the representation is fitted at the end of every loop on all of D.
TEST(MapElitesLoop, ReconstructionErrorsAndFitting) {
  World w(true, 2, 2);
  World::queue(*w.initial, {{1, 3, 4}, {2, 0, 0}});
  w.loop->run_loop(0);
  EXPECT_DOUBLE_EQ(w.archive->recn_error(static_cast<std::size_t>(w.archive->slot_of(1))), 5.0);  // ‖(3, 4)‖
  EXPECT_DOUBLE_EQ(w.archive->mean_recn_error(), 2.5);
  World::queue(*w.mutator, {{5, 6, 8}, {6, 1, 0}});  // parameter space: errors 10 and 1
  w.mutator->latent_origin = true;
  World::queue(*w.mutator, {{7, 0, 0}, {8, 0, 0}});  // latent space: θ′ = Dec(z′)
  w.mutator->latent_origin = false;
  w.loop->run_loop(1);
  const auto err = [&](std::int64_t cell) {
    return w.archive->recn_error(static_cast<std::size_t>(w.archive->slot_of(cell)));
  };
  EXPECT_DOUBLE_EQ(err(5), 10.0);
  EXPECT_DOUBLE_EQ(err(6), 1.0);
  EXPECT_EQ(err(7), 0.0);
  EXPECT_EQ(err(8), 0.0);
  EXPECT_EQ(w.model->fitted_loops, (std::vector<int>{0, 1}));
  EXPECT_EQ(w.model->fitted_sizes, (std::vector<std::size_t>{2, 6}));
  EXPECT_EQ(w.recorder.trained, (std::vector<int>{0, 1}));
}

// Every iteration counts its batch; the metrics see the mutator's mixing ratio as it reported it.
TEST(MapElitesLoop, CountsEvaluationsAndPassesTheMixingRatio) {
  World w(false, 4, 6);
  World::queue(*w.initial, {{1, 0}, {2, 0}, {3, 0}, {4, 0}, {5, 0}, {6, 0}});
  w.loop->run_loop(0);
  World::queue(*w.mutator, std::vector<std::vector<double>>(8, {7, 0}));
  w.loop->run_loop(1);
  EXPECT_EQ(w.loop->evaluations(), 6u + 2u * 4u);
  ASSERT_EQ(w.recorder.mixing.size(), 3u);
  EXPECT_EQ(w.recorder.mixing[1], 0.25);
  EXPECT_EQ(w.recorder.outcomes[2].iteration, 1);
  EXPECT_EQ(w.recorder.outcomes[2].loop, 1);
}

// Issue 20: a non-finite fitness or descriptor value makes that evaluation invalid (counted, never
// stored), in loop 0 and in later loops alike.
TEST(MapElitesLoop, NonFiniteFitnessOrDescriptorIsInvalidAndNeverStored) {
  World w(false, 4, 4);
  World::queue(*w.initial, {{1, 0, 0, kNanFitness}, {2, 0, 0, kInfDescriptor}, {3, 5}, {4, 6}});
  w.loop->run_loop(0);
  EXPECT_EQ(w.archive->size(), 2u);
  EXPECT_EQ(w.archive->slot_of(1), -1);
  EXPECT_EQ(w.archive->slot_of(2), -1);
  EXPECT_EQ(w.recorder.outcomes[0].invalid, 2u);
  World::queue(*w.mutator, {{3, 9, 0, kNanFitness}, {4, 9, 0, kInfDescriptor}, {5, 1}, {6, 1}});
  World::queue(*w.mutator, std::vector<std::vector<double>>(4, {7, 0}));
  w.s.insertion = InsertionRule::kFitness;  // a NaN would otherwise win or block a cell forever
  w.loop->run_loop(1);
  EXPECT_EQ(w.param(3, 1), 5.0);
  EXPECT_EQ(w.param(4, 1), 6.0);
  EXPECT_EQ(w.recorder.outcomes[1].invalid, 2u);
  for (std::size_t slot = 0; slot < w.archive->size(); ++slot) {
    EXPECT_TRUE(std::isfinite(w.archive->fitness(slot)));
    EXPECT_TRUE(std::isfinite(w.archive->descriptor(slot)[0]));
  }
}

// A cell index outside the grid is a PluginError naming the descriptor and the offspring, raised
// before the archive is touched.
TEST(MapElitesLoop, CellOutOfRangeIsAPluginErrorBeforeTheArchive) {
  World w(false, 4, 3);
  w.c.descriptor_label = "descriptor 'scripted' (test)";
  World::queue(*w.initial, {{1, 0}, {2, 0, 0, kCellOutOfRange}, {3, 0}});
  try {
    w.loop->run_loop(0);
    FAIL() << "expected a PluginError";
  } catch (const PluginError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("descriptor 'scripted' (test) returned cell 50, outside its grid's [0, 50)"), std::string::npos)
        << what;
    EXPECT_NE(what.find("offspring 1 of loop 0, iteration 0"), std::string::npos) << what;
  }
  EXPECT_EQ(w.archive->size(), 0u);
}

// A mutator's batch of the wrong shape or with a non-finite parameter is a PluginError naming it.
TEST(MapElitesLoop, BadMutatorOutputIsAPluginError) {
  World w(false, 4, 2);
  w.c.mutator_label = "mutator 'scripted' (test)";
  World::queue(*w.initial, {{1, 0}, {2, 0}});
  w.loop->run_loop(0);
  World::queue(*w.mutator, {{3, 0}, {4, NAN}, {5, 0}, {6, 0}});
  try {
    w.loop->run_loop(1);
    FAIL() << "expected a PluginError";
  } catch (const PluginError& e) {
    EXPECT_NE(std::string(e.what()).find("mutator 'scripted' (test) returned parameter nan (offspring 1, parameter 1) "
                                         "in loop 1, iteration 0"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(w.archive->size(), 2u);
}

// A representation's non-finite output is a PluginError naming the representation.
TEST(MapElitesLoop, BadRepresentationOutputIsAPluginErrorNamingIt) {
  World w(true, 4, 2);
  w.c.representation_label = "representation 'first' (test)";
  World::queue(*w.initial, {{1, 0}, {2, 0}});
  w.loop->run_loop(0);
  w.model->nan_decode = true;
  World::queue(*w.mutator, std::vector<std::vector<double>>(4, {3, 0}));
  try {
    w.loop->run_loop(1);
    FAIL() << "expected a PluginError";
  } catch (const PluginError& e) {
    EXPECT_NE(std::string(e.what()).find("representation 'first' (test) decode() returned nan (row 0, column 0)"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(w.archive->size(), 2u);
}
