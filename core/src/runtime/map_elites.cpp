#include "runtime/map_elites.hpp"

#include "runtime/clock.hpp"

#include <qd/errors.hpp>
#include <qd/rng.hpp>

#include <algorithm>
#include <numeric>

namespace qd::runtime {

MapElites::MapElites(const ExperimentSettings& settings, Components& components, Evaluator& evaluator, Archive& archive,
                     Dataset& dataset, LoopObserver& observer)
    : s_(settings),
      c_(components),
      evaluator_(evaluator),
      archive_(archive),
      dataset_(dataset),
      observer_(observer),
      checks_(components),
      representation_(components, checks_) {}

void MapElites::run_loop(int loop) {
  if (loop == 0) {
    initial_sampling();
  } else {
    new_cells_.clear();
    call_plugin(c_.mutator_label, "begin_loop()", [&] {
      c_.mutator->begin_loop(LoopContext{loop, &archive_, &dataset_, &representation_});
    });
    for (int it = 0; it < s_.iterations; ++it) iterate(loop, it);
    // D gains the current occupant of every cell discovered in this loop (paper, Sec. 3).
    for (std::int64_t cell : new_cells_)
      dataset_.add(archive_.params(static_cast<std::size_t>(archive_.slot_of(cell))), cell, loop);
  }
  fit_representation(loop);
}

void MapElites::initial_sampling() {
  const auto n = static_cast<std::size_t>(s_.initial_samples);
  const std::size_t P = c_.shape.param_count();
  parents_.theta.resize(0, static_cast<Eigen::Index>(P));  // samplers take no parents
  offspring_.reset(n, P, 0);
  Rng rng(s_.seed, Stream::kInitial, 0);
  MutateContext mctx{0, 0, &rng, &representation_, &archive_};
  call_plugin(c_.initial_label, "mutate()", [&] { c_.initial->mutate(parents_, n, mctx, offspring_); });
  checks_.offspring(offspring_, true, n, 0, 0, 0);

  seeds_.resize(n);
  for (std::size_t i = 0; i < n; ++i) seeds_[i] = Rng::derive_seed(s_.seed, Stream::kEpisode, 0, 0, i);
  evaluate(0, 0);
  evaluations_ += n;

  // The archive starts as the first-sampled policy of each distinct cell (never a replacement).
  IterationOutcome outcome{0, 0, &offspring_};
  for (std::size_t i = 0; i < n; ++i) {
    const auto row = static_cast<Eigen::Index>(i);
    if (evaluated_.cells[i] < 0) {
      ++outcome.invalid;
      continue;
    }
    const Insertion r = archive_.offer(evaluated_.cells[i], offspring_.theta.row(row).data(),
                                       evaluated_.descriptors.row(row).data(), evaluated_.fitness[i], 0.0, false);
    if (r == Insertion::kAdded) ++outcome.added;
  }
  // D = the archive. The reference builds it with np.unique over one-hot rows, which orders it by
  // descending cell index; "insertion" keeps the archive's order.
  std::vector<std::size_t> slots(archive_.size());
  std::iota(slots.begin(), slots.end(), std::size_t{0});
  if (s_.dataset_order == DatasetOrder::kReference)
    std::sort(slots.begin(), slots.end(), [&](auto a, auto b) { return archive_.cell(a) > archive_.cell(b); });
  for (std::size_t slot : slots) dataset_.add(archive_.params(slot), archive_.cell(slot), 0);
  observer_.iteration_done(outcome);
}

void MapElites::iterate(int loop, int it) {
  const auto batch = static_cast<std::size_t>(s_.batch);
  const std::size_t P = c_.shape.param_count();
  const auto LD = static_cast<std::size_t>(c_.representation->latent_size());
  const auto l = static_cast<std::uint64_t>(loop), i = static_cast<std::uint64_t>(it);

  // 1. Selection: uniform over the elites (samplers such as ps-uniform take no parents).
  if (c_.mutator->uses_parents()) {
    if (archive_.size() == 0) throw Error("the archive is empty after loop 0: no initial sample could be described");
    Rng rng(s_.seed, Stream::kSelection, l, i);
    archive_.select(batch, rng, parents_);
  } else {
    parents_.theta.resize(0, static_cast<Eigen::Index>(P));
    parents_.recn_error.resize(0);
    parents_.cells.clear();
  }

  // 2. Variation.
  offspring_.reset(batch, P, LD);
  Rng rng(s_.seed, Stream::kMutation, l, i);
  MutateContext mctx{loop, it, &rng, &representation_, &archive_};
  call_plugin(c_.mutator_label, "mutate()", [&] { c_.mutator->mutate(parents_, batch, mctx, offspring_); });
  checks_.offspring(offspring_, false, batch, LD, loop, it);
  reconstruction_errors(offspring_);

  // 3. Evaluation: one episode per offspring, seeded by its place in the run.
  seeds_.resize(batch);
  for (std::size_t k = 0; k < batch; ++k) seeds_[k] = Rng::derive_seed(s_.seed, Stream::kEpisode, l, i, k);
  evaluate(loop, it);
  evaluations_ += batch;

  // 4. Insertion, then the mutator hears what became of its offspring.
  IterationOutcome outcome{loop, it, &offspring_};
  insert(loop, it, outcome);
  Feedback fb;
  fb.loop = loop;
  fb.iteration = it;
  fb.offspring = batch;
  fb.added = outcome.added;
  fb.replaced = outcome.replaced;
  fb.rejected = outcome.rejected;
  fb.invalid = outcome.invalid;
  fb.results = &results_;
  call_plugin(c_.mutator_label, "feedback()", [&] { c_.mutator->feedback(fb); });
  observer_.iteration_done(outcome);
}

void MapElites::evaluate(int loop, int it) {
  try {
    evaluator_.evaluate(offspring_.theta, seeds_, evaluations_, evaluated_);
    checks_.evaluations(evaluated_, loop, it);
  } catch (const EvaluationFault& f) {
    const std::string which = f.first == f.last
                                  ? "offspring " + std::to_string(f.first)
                                  : "one of offspring " + std::to_string(f.first) + " to " + std::to_string(f.last);
    const std::string file = f.first <= f.last && f.last < static_cast<std::size_t>(offspring_.theta.rows())
                                 ? observer_.fault_offspring(loop, it, f.first, f.last, offspring_.theta, seeds_)
                                 : "";
    throw PluginError(std::string(f.what()) + " (" + which + " of loop " + std::to_string(loop) + ", iteration " +
                      std::to_string(it) + (file.empty() ? "" : "; parameters and episode seed in " + file) + ")");
  }
}

void MapElites::insert(int loop, int it, IterationOutcome& outcome) {
  // Sequential, in offspring order. An empty cell takes the offspring; an occupied one is replaced
  // with probability replace_probability (a coin drawn only for occupied cells: the paper's random
  // replacement), or, with insertion = "fitness", when the offspring's fitness is higher.
  const bool by_fitness = s_.insertion == InsertionRule::kFitness;
  const bool has_model = c_.representation->latent_size() > 0;
  Rng coin(s_.seed, Stream::kInsertion, static_cast<std::uint64_t>(loop), static_cast<std::uint64_t>(it));
  const std::size_t n = evaluated_.cells.size();
  results_.assign(n, OffspringResult{});
  for (std::size_t k = 0; k < n; ++k) {
    OffspringResult& r = results_[k];
    const std::int64_t cell = evaluated_.cells[k];
    if (cell < 0) {
      ++outcome.invalid;
      continue;
    }
    r.cell = cell;
    r.fitness = evaluated_.fitness[k];
    bool replace = false;
    if (archive_.occupied(cell)) {
      r.previous = archive_.fitness(static_cast<std::size_t>(archive_.slot_of(cell)));
      replace = by_fitness ? r.fitness > r.previous : coin.uniform() < s_.replace_probability;
    }
    const auto row = static_cast<Eigen::Index>(k);
    switch (archive_.offer(cell, offspring_.theta.row(row).data(), evaluated_.descriptors.row(row).data(), r.fitness,
                           has_model ? recn_[row] : 0.0, replace)) {
      case Insertion::kAdded:
        r.outcome = Outcome::kNewCell;
        ++outcome.added;
        new_cells_.push_back(cell);
        break;
      case Insertion::kReplaced:
        r.outcome = r.fitness > r.previous ? Outcome::kImproved : Outcome::kReplaced;
        ++outcome.replaced;
        break;
      case Insertion::kRejected:
        r.outcome = Outcome::kDiscarded;
        ++outcome.rejected;
        break;
    }
  }
}

void MapElites::reconstruction_errors(Offspring& off) {
  if (c_.representation->latent_size() == 0) {
    recn_.setZero(off.theta.rows());
    return;
  }
  // Offspring made in parameter space have no latent origin: z′ = Enc(θ′).
  std::vector<Eigen::Index> missing;
  for (std::size_t k = 0; k < off.has_latent.size(); ++k)
    if (!off.has_latent[k]) missing.push_back(static_cast<Eigen::Index>(k));
  if (!missing.empty()) {
    Matrix theta(static_cast<Eigen::Index>(missing.size()), off.theta.cols());
    for (std::size_t k = 0; k < missing.size(); ++k)
      theta.row(static_cast<Eigen::Index>(k)) = off.theta.row(missing[k]);
    Matrix z;
    representation_.encode(theta, z);
    for (std::size_t k = 0; k < missing.size(); ++k) off.latent.row(missing[k]) = z.row(static_cast<Eigen::Index>(k));
  }
  Matrix decoded;
  representation_.decode(off.latent, decoded);
  recn_ = (off.theta - decoded).rowwise().norm();
}

void MapElites::fit_representation(int loop) {
  if (c_.representation->latent_size() == 0) return;
  observer_.training_started(loop);
  const double t0 = now_seconds();
  const FitReport report = representation_.fit(dataset_, FitContext{loop, s_.seed, observer_.training_log()});
  observer_.training_done(loop, report, now_seconds() - t0);
  if (loop == 0) {
    // At loop 1 the archive is rebuilt from D with the errors of the loop-0 model (paper, Sec. 3);
    // later errors stay as stored at insertion (the reference's stale values).
    Vector err;
    representation_.reconstruction_errors(Matrix(dataset_.params()), err);
    for (std::size_t k = 0; k < dataset_.size(); ++k)
      archive_.set_recn_error(static_cast<std::size_t>(archive_.slot_of(dataset_.cells()[k])),
                              err[static_cast<Eigen::Index>(k)]);
  }
}

}  // namespace qd::runtime
