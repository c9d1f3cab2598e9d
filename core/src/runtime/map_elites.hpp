// The MAP-Elites loop of Policy Manifold Search (Rakicevic, Cully, Kormushev; the paper's Sec. 3
// and its Algorithm 1). Every algorithm of the paper is this loop with another representation
// and mutator (docs: the algorithm table).
//
//   loop 0:   sample policies, evaluate them, fill the archive with the first policy of each
//             cell, put the archive into the dataset D, fit the representation on D.
//   loop n:   iterations × { select parents, mutate, evaluate, insert }, then add the policies of
//             the cells discovered in this loop to D and fit the representation on D again.
//
// Everything else a run does (files, checkpoints, progress) happens around this class, through
// LoopObserver.
#pragma once

#include "runtime/components.hpp"
#include "runtime/evaluator.hpp"
#include "runtime/experiment.hpp"
#include "runtime/grid_archive.hpp"
#include "runtime/plugin_output_checks.hpp"

#include <qd/dataset.hpp>
#include <qd/mutator.hpp>
#include <qd/representation.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace qd::runtime {

// What one iteration did (loop 0 is one iteration).
struct IterationOutcome {
  int loop = 0;
  int iteration = 0;
  const Offspring* offspring = nullptr;
  std::size_t added = 0, replaced = 0, rejected = 0, invalid = 0;
};

class LoopObserver {
 public:
  virtual ~LoopObserver() = default;
  virtual void iteration_done(const IterationOutcome& outcome) = 0;
  virtual void training_started(int /*loop*/) {}
  virtual void training_done(int loop, const FitReport& report, double seconds) = 0;
  // Where the representation's fit() logs (FitContext::log); null: nowhere.
  virtual TrainingLog* training_log() { return nullptr; }
  // A plugin failed on offspring [first, last] of the batch of `loop`, `iteration` (0 <= first <=
  // last < theta.rows()): the run may keep their parameters (rows of `theta`) and episode seeds.
  // Returns the file that now holds them, or "" when none does.
  virtual std::string fault_offspring(int /*loop*/, int /*iteration*/, std::size_t /*first*/, std::size_t /*last*/,
                                      const Matrix& /*theta*/, const std::vector<std::uint64_t>& /*seeds*/) {
    return "";
  }
};

class MapElites {
 public:
  MapElites(const ExperimentSettings& settings, Components& components, Evaluator& evaluator, Archive& archive,
            Dataset& dataset, LoopObserver& observer);

  // Runs loop `loop` (0 = the initial random phase) and fits the representation at its end.
  void run_loop(int loop);
  // Loop 0 without the fit: what `qdrun --dry-run` times to estimate a run's cost.
  void initial_sampling();

  std::uint64_t evaluations() const noexcept { return evaluations_; }
  void set_evaluations(std::uint64_t n) noexcept { evaluations_ = n; }  // when resuming

 private:
  void iterate(int loop, int iteration);
  // Evaluates offspring_.theta with seeds_ into evaluated_ and checks the result. A plugin fault on
  // particular offspring is rethrown with the loop, iteration and offspring index, and the observer
  // may keep their parameters and episode seeds (LoopObserver::fault_offspring).
  void evaluate(int loop, int iteration);
  // Inserts the evaluated batch in offspring order and counts what happened.
  void insert(int loop, int iteration, IterationOutcome& outcome);
  // ‖θ′ − Dec(z′)‖ of every offspring, z′ = its latent origin or Enc(θ′) (0 without a model).
  void reconstruction_errors(Offspring& offspring);
  void fit_representation(int loop);

  const ExperimentSettings& s_;
  Components& c_;
  Evaluator& evaluator_;
  Archive& archive_;
  Dataset& dataset_;
  LoopObserver& observer_;
  PluginOutputChecks checks_;
  CheckedRepresentation representation_;  // c_.representation, its output checked
  std::uint64_t evaluations_ = 0;

  // Per-iteration buffers, kept to avoid reallocating multi-megabyte batches.
  Parents parents_;
  Offspring offspring_;
  Vector recn_;
  std::vector<std::uint64_t> seeds_;
  Evaluations evaluated_;
  std::vector<OffspringResult> results_;
  std::vector<std::int64_t> new_cells_;  // cells first filled in this loop, in order
};

}  // namespace qd::runtime
