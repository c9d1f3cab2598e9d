// Sweeps, stage 2: the estimate (sweep_stages.hpp). --dry-run prices each planned run in
// core-hours from a pilot of its loop 0 (runtime/cost_estimate.hpp), or from a resumed run's own loops.
#include "sweep_stages.hpp"

#include "runtime/components.hpp"
#include "runtime/cost_estimate.hpp"
#include "runtime/evaluator.hpp"
#include "runtime/run_directory.hpp"

#include <qd/errors.hpp>

#include <toml++/toml.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <sstream>

namespace qd::app {
namespace fs = std::filesystem;
using runtime::Document;
using runtime::Registry;

namespace {

// The settings a loop-0 pilot depends on: runs that share them share the pilot's episode costs.
std::string pilot_key(const std::string& resolved_toml) {
  std::string key;
  for (const auto& [name, value] : runtime::config_values(resolved_toml, "the resolved configuration"))
    for (const char* prefix : {"environment.", "descriptor.", "initial.", "policy.", "experiment.initial_samples"})
      if (name.rfind(prefix, 0) == 0) key += name + " = " + value + "\n";
  return key;
}

std::string hours(double seconds) {
  char buf[32];
  std::snprintf(buf, sizeof buf, seconds < 36 ? "%.3f" : "%.2f", seconds / 3600.0);
  return buf;
}

// What a resumed run's completed loops cost it per evaluation, in core-seconds: its metrics.csv
// (wall time, training out) times the workers of the session that ran the loop measured.
struct MeasuredCost {
  double core_seconds_per_evaluation = 0.0;  // 0: nothing to go on
  int loop = -1;
  int workers = 1;
};

MeasuredCost measured_cost(const fs::path& dir, int iterations) {
  std::istringstream metrics(read_text(dir / "metrics.csv"));
  const runtime::MeasuredRate rate = runtime::measured_rate(metrics, iterations);
  MeasuredCost out;
  if (rate.loop < 1) return out;
  try {
    const fs::path path = runtime::session_provenance(dir, rate.loop);
    const toml::table provenance = toml::parse(read_text(path), path.string());
    out.workers = std::max<int>(1, provenance["workers"].value_or(1));
  } catch (const toml::parse_error&) {
    // Unreadable provenance: one worker, the sweep's default.
  }
  out.loop = rate.loop;
  out.core_seconds_per_evaluation = rate.seconds_per_evaluation * out.workers;
  return out;
}

}  // namespace

void print_cost_estimate(const SweepOptions& o, const std::vector<PlannedRun>& runs,
                         const std::vector<std::size_t>& pending, RegistryCache& regs, int concurrent, int workers,
                         int hw) {
  std::map<std::string, runtime::EpisodePilot> pilots;
  double episodes = 0, training = 0;
  std::printf(
      "estimate (one core per run; episodes from a pilot of loop 0 and of its offspring and the file's [cost], or "
      "from a resumed run's own loops; training timed by the representation):\n");
  for (std::size_t i : pending) {
    const PlannedRun& r = runs[i];
    Document doc = read_run_document(o, r.file, r.seed, r.overrides);
    const Registry& reg = regs.get(doc.plugin_paths());
    runtime::Experiment ex = runtime::resolve(doc, reg);
    const runtime::CostModel cost = runtime::read_cost_model(doc);
    runtime::Components c = runtime::build_components(ex, reg);
    const std::string key = pilot_key(ex.resolved_toml);
    auto it = pilots.find(key);
    runtime::CostEstimate e;
    // A resumed run that has completed a loop past 0 is priced at its own measured rate.
    const MeasuredCost measured = r.first_loop > 1 ? measured_cost(r.dir, ex.settings.iterations) : MeasuredCost{};
    try {
      if (it == pilots.end()) it = pilots.emplace(key, runtime::run_episode_pilot(ex.settings, c)).first;
      e = runtime::estimate_run_cost(ex.settings, cost, c, it->second, r.first_loop,
                                     {measured.core_seconds_per_evaluation, measured.loop});
    } catch (const PluginError& fault) {
      // Plugin code failed while running (the pilot's episodes, the model's timing): as in a run, exit 3.
      throw runtime::WorkerFailure(std::string(fault.what()) + " (in the --dry-run estimate of " + r.label + ")");
    }
    const runtime::EpisodePilot& p = it->second;
    episodes += e.episode_seconds;
    training += e.training_seconds;
    // What priced the episodes: the run's own loops, or the pilot (whose offspring count only for
    // a run that breeds from elites), and the lengthening [cost] adds to a breeding run's.
    char basis[384], growth[96] = "";
    const runtime::CostEstimate::Lengthening& l = e.lengthening;
    if (l.first_loop <= l.last_loop)
      std::snprintf(growth, sizeof growth, "; [cost]: %s x%.2f to x%.2f over loops %d-%d",
                    measured.core_seconds_per_evaluation > 0 ? "that" : "loop 0's", l.from, l.to, l.first_loop,
                    l.last_loop);
    if (measured.core_seconds_per_evaluation > 0)
      std::snprintf(basis, sizeof basis, "measured in its loop %d: %.2f ms/evaluation x %d worker%s%s", measured.loop,
                    1e3 * measured.core_seconds_per_evaluation / measured.workers, measured.workers,
                    measured.workers == 1 ? "" : "s", growth);
    else if (c.mutator->uses_parents())
      std::snprintf(basis, sizeof basis,
                    "loop 0: %.2f ms/episode, %.0f of %d steps, |D| %zu; offspring: %.2f ms/episode, %.0f steps%s",
                    1e3 * p.seconds_per_episode(), p.mean_steps, p.max_steps, p.loop0_archive,
                    1e3 * p.offspring_seconds_per_episode(), p.offspring_mean_steps, growth);
    else
      std::snprintf(basis, sizeof basis, "loop 0: %.2f ms/episode, %.0f of %d steps, |D| %zu",
                    1e3 * p.seconds_per_episode(), p.mean_steps, p.max_steps, p.loop0_archive);
    // The pilot's worlds are fresh; state a run's persistent worlds build up over it (the
    // reference's ghost balls made a 102 000-evaluation run about 8 times longer) is not priced.
    if (const int worlds = c.environment->info().persistent_worlds; worlds > 0) {
      char unpriced[160];
      std::snprintf(unpriced, sizeof unpriced,
                    "; not priced: what its %d persistent worlds accumulate (the pilot's worlds are fresh)", worlds);
      std::strncat(basis, unpriced, sizeof basis - std::strlen(basis) - 1);
    }
    // The dataset the training was priced on, where there is any.
    if (e.training_seconds > 0) {
      char rows[96];
      if (e.dataset_rows_from_cost)
        std::snprintf(rows, sizeof rows, "; |D| at the last fit %zu ([cost] cells)", e.dataset_rows_last);
      else
        std::snprintf(rows, sizeof rows, "; |D| at the last fit %zu (loop 0's x (1 + %.1f sqrt(loop)))",
                      e.dataset_rows_last, runtime::kDatasetGrowth);
      std::strncat(basis, rows, sizeof basis - std::strlen(basis) - 1);
    }
    std::printf("  %-44s %8s core-h: %lld evaluations %s h, training %s h (%s)\n", r.label.c_str(),
                hours(e.total_seconds()).c_str(), e.evaluations, hours(e.episode_seconds).c_str(),
                hours(e.training_seconds).c_str(), basis);
    std::fflush(stdout);
  }
  const int cores = std::max(1, std::min(hw, concurrent * workers));
  std::printf(
      "sweep: estimated %s core-hours (episodes %s, training %s); on this machine, %d at a time on %d core%s: "
      "about %s hours\n",
      hours(episodes + training).c_str(), hours(episodes).c_str(), hours(training).c_str(), concurrent, cores,
      cores == 1 ? "" : "s", hours((episodes + training) / cores).c_str());
}

}  // namespace qd::app
