// What a run will cost before it starts (`qdrun --dry-run`): core-seconds of episodes and of
// training, from a pilot of the run's own loop 0 and the representation's measured fit time.
//
// The model (docs/user-guide.md, "How long will it take"):
//  * Episodes. The pilot runs loop 0 as the run would (same policies, same seeds), with one
//    supervised worker process, and measures seconds per world step and the mean episode length s0. An episode costs
//    its steps times that rate. Samplers (mutators without parents: ps-uniform, ps-glorot) keep drawing loop-0-like
//    policies, so their episodes stay at s0. Mutation operators breed from elites that learn to stay alive, so their
//    episodes lengthen; they are taken to average s0 + growth * (max_steps - s0) from loop 1 on, where `growth` is
//    kEpisodeGrowth (fitted on full-length Walker, Kicker and Striker runs; documented there).
//  * Training. D holds the loop-0 archive after loop 0 (the pilot counts it), D0, and then about
//    D0 (1 + kDatasetGrowth sqrt(loop)), up to the grid's size; the representation times its own
//    fit on data of those sizes (Representation::estimate_fit_seconds).
#pragma once

#include "runtime/components.hpp"
#include "runtime/experiment.hpp"

#include <cstddef>
#include <vector>

namespace qd::runtime {

// The fraction of the way from the loop-0 episode length to max_steps that the episodes of
// mutation operators average from loop 1 on (docs/performance.md, "Dry-run cost model").
inline constexpr double kEpisodeGrowth = 0.4;
// |D| at loop l is about D0 (1 + kDatasetGrowth sqrt(l)) (fitted on Walker runs: 1.1 to 1.5).
inline constexpr double kDatasetGrowth = 1.2;

struct EpisodePilot {
  std::size_t episodes = 0;       // loop-0 policies rolled out
  double seconds = 0.0;           // their rollouts and descriptors, one worker
  double mean_steps = 0.0;        // s0
  int max_steps = 0;              // the environment's episode cap
  std::size_t loop0_archive = 0;  // distinct cells they reached: |D| after loop 0
  double seconds_per_step() const { return mean_steps > 0 ? seconds / (mean_steps * episodes) : 0.0; }
};

// Runs the experiment's loop 0 (initial sampler, episodes, descriptors, archive) with one worker
// process, without the representation's fit. Throws what the run would throw.
EpisodePilot run_episode_pilot(const ExperimentSettings& settings, Components& components);

struct CostEstimate {
  double episode_seconds = 0.0;   // one core
  double training_seconds = 0.0;  // one core
  long long evaluations = 0;      // that these loops run
  double total_seconds() const { return episode_seconds + training_seconds; }
};

// Loops [first_loop, settings.loops) of the run: `first_loop` > 0 for a run that resumes.
// Asks the representation to time its fits (a plugin call, checked).
CostEstimate estimate_run_cost(const ExperimentSettings& settings, Components& components, const EpisodePilot& pilot,
                               int first_loop = 0);

// The dataset size the model assumes at loop `loop`'s fit.
std::size_t expected_dataset_rows(const EpisodePilot& pilot, std::int64_t cells, int loop);

}  // namespace qd::runtime
