// What a run will cost before it starts (`qdrun --dry-run`): core-seconds of episodes and of
// training, from a pilot of the run's own loop 0 and the representation's measured fit time.
//
// The model (docs/user-guide.md, "How long will it take"; checked in docs/performance.md, "Dry-run cost model"):
//  * Episodes. The pilot runs loop 0 as the run would (same policies, same seeds), with one
//    supervised worker process, and times its episodes. Samplers (mutators without parents:
//    ps-uniform, ps-glorot) keep drawing loop-0-like policies, so their episodes cost what loop 0's
//    did. Mutation operators breed from elites, whose offspring can live longer or shorter than
//    random policies depending on the environment; so the pilot then rolls out as many offspring
//    of the loop-0 archive (uniform parents, theta + kPilotSigma N(0, I): the reference's MAPE-Iso
//    operator, no model needed) and prices every episode from loop 1 on at their measured time.
//    What it cannot see is a lengthening that builds up over many loops as the archive reaches
//    cells only long episodes reach (the Walker's, docs/performance-history.md). An experiment file states
//    it in [cost] (CostModel; qdreport measures it from finished runs): then, from loop 1 on, a
//    mutation operator's episodes cost loop 0's time times cost.offspring_time at the loop's
//    middle evaluation. A resumed run that has completed a loop past 0 is priced at its own
//    measured rate instead (measured_rate), grown as [cost] grows from that loop on, so re-running
//    --dry-run on a sweep in progress tracks what it has measured.
//  * Training. D holds the loop-0 archive after loop 0 (the pilot counts it), D0, and then one
//    policy per cell found by the end of each loop: [cost]'s `cells` at that loop's last evaluation
//    where the file states them (measured on long runs, as offspring_time), otherwise about
//    D0 (1 + kDatasetGrowth sqrt(loop)); never beyond the grid's size. The representation times its
//    own fit on data of those sizes (Representation::estimate_fit_seconds).
#pragma once

#include "runtime/components.hpp"
#include "runtime/cost_model.hpp"
#include "runtime/experiment.hpp"

#include <cstddef>
#include <istream>
#include <vector>

namespace qd::runtime {

// The step size of the pilot's offspring, theta + kPilotSigma N(0, I) (the reference's MAPE-Iso).
inline constexpr double kPilotSigma = 0.1;
// Without [cost] cells, |D| at loop l is about D0 (1 + kDatasetGrowth sqrt(l)): fitted on the
// Walker's loop 0 of 2000 (1.1 to 1.5); where loop 0 is small (the reference Walker's 200) archives
// outgrow it many times over, hence [cost] cells.
inline constexpr double kDatasetGrowth = 1.2;

struct EpisodePilot {
  std::size_t episodes = 0;       // loop-0 policies rolled out
  double seconds = 0.0;           // their rollouts and descriptors, one worker
  double mean_steps = 0.0;        // their mean episode length
  int max_steps = 0;              // the environment's episode cap
  std::size_t loop0_archive = 0;  // distinct cells they reached: |D| after loop 0
  // Offspring of the loop-0 archive, timed the same way.
  std::size_t offspring_episodes = 0;
  double offspring_seconds = 0.0;
  double offspring_mean_steps = 0.0;

  double seconds_per_episode() const { return episodes > 0 ? seconds / static_cast<double>(episodes) : 0.0; }
  // Loop 0's time when there were no elites to breed from.
  double offspring_seconds_per_episode() const {
    return offspring_episodes > 0 ? offspring_seconds / static_cast<double>(offspring_episodes) : seconds_per_episode();
  }
};

// Runs the experiment's loop 0 (initial sampler, episodes, descriptors, archive) with one worker
// process, without the representation's fit, then as many offspring of its archive (theta + sigma
// N(0, I), uniform parents; seeded as the run's first iteration). Throws what the run would throw.
EpisodePilot run_episode_pilot(const ExperimentSettings& settings, Components& components,
                               double offspring_sigma = kPilotSigma);

struct CostEstimate {
  double episode_seconds = 0.0;   // one core
  double training_seconds = 0.0;  // one core
  long long evaluations = 0;      // that these loops run
  // The [cost] lengthening applied to loops first_loop..last_loop (none when first_loop >
  // last_loop): times loop 0's time, or times the resumed run's own measured rate.
  struct Lengthening {
    int first_loop = 1, last_loop = 0;
    double from = 1.0, to = 1.0;
  } lengthening;
  std::size_t dataset_rows_last = 0;    // |D| at the last loop's fit
  bool dataset_rows_from_cost = false;  // sized by [cost] cells, not by the growth rule
  double total_seconds() const { return episode_seconds + training_seconds; }
};

// A resumed run's own cost: the median wall seconds per evaluation (training taken out) over the
// iterations of the last loop >= 1 that metrics.csv shows complete, and that loop; {0, -1} when
// there is none. Episodes lengthen as an archive spreads (the Walker's do for many loops), which no
// pilot of loop 0 can see; a run that has done a loop has measured it.
struct MeasuredRate {
  double seconds_per_evaluation = 0.0;
  int loop = -1;
};
MeasuredRate measured_rate(std::istream& metrics_csv, int iterations);

// Loops [first_loop, settings.loops) of the run: `first_loop` > 0 for a run that resumes.
// `cost` is the experiment file's [cost] (read_cost_model).
// `measured` (a resumed run's own rate in core-seconds, from measured_rate), when positive, prices
// its evaluations instead of the pilot. Asks the representation to time its fits (a plugin call, checked).
CostEstimate estimate_run_cost(const ExperimentSettings& settings, const CostModel& cost, Components& components,
                               const EpisodePilot& pilot, int first_loop = 0, MeasuredRate measured = {});

// The evaluations done at the middle of loop `loop` >= 1 (where [cost] is read for it).
double loop_midpoint_evaluations(const ExperimentSettings& settings, int loop);

// The evaluations done when loop `loop` ends (loop 0: the initial samples).
double loop_end_evaluations(const ExperimentSettings& settings, int loop);

// The dataset size the model assumes at the fit after loop `loop`, on a grid of `cells` cells.
std::size_t expected_dataset_rows(const ExperimentSettings& settings, const CostModel& cost, const EpisodePilot& pilot,
                                  std::int64_t cells, int loop);

}  // namespace qd::runtime
