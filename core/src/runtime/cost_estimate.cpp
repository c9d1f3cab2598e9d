#include "runtime/cost_estimate.hpp"

#include "runtime/clock.hpp"
#include "runtime/evaluator.hpp"
#include "runtime/grid_archive.hpp"
#include "runtime/map_elites.hpp"
#include "runtime/plugin_output_checks.hpp"

#include <qd/dataset.hpp>
#include <qd/errors.hpp>
#include <qd/planning.hpp>
#include <qd/rng.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <sstream>
#include <string>

namespace qd::runtime {
namespace {

// One supervised worker process (a crash or hang in plugin code is reported naming it, as in a
// run), timed, counting world steps.
class TimedEvaluator final : public Evaluator {
 public:
  TimedEvaluator(const ExperimentSettings& s, const Components& c) {
    EvaluatorSpec spec;
    spec.backend = Backend::kProcesses;
    spec.workers = 1;
    spec.capacity = static_cast<std::size_t>(s.initial_samples);
    spec.timeout_seconds = s.timeout_seconds;
    spec.labels = {c.environment_label, c.descriptor_label};
    spec.fresh_worlds = true;  // the pilot prices episodes; persistent worlds stay untouched
    inner_ = make_evaluator(spec, *c.environment, *c.descriptor, c.shape);
  }
  int workers() const noexcept override { return 1; }
  const char* backend() const noexcept override { return inner_->backend(); }
  void evaluate(const Matrix& params, const std::vector<std::uint64_t>& seeds, std::uint64_t first_episode,
                Evaluations& out) override {
    const double start = now_seconds();
    inner_->evaluate(params, seeds, first_episode, out);
    seconds += now_seconds() - start;
    episodes += out.steps.size();
    steps += std::accumulate(out.steps.begin(), out.steps.end(), 0.0);
  }
  double seconds = 0.0, steps = 0.0;
  std::size_t episodes = 0;

 private:
  std::unique_ptr<Evaluator> inner_;
};

class SilentObserver final : public LoopObserver {
  void iteration_done(const IterationOutcome&) override {}
  void training_done(int, const FitReport&, double) override {}
};

}  // namespace

EpisodePilot run_episode_pilot(const ExperimentSettings& settings, Components& c, double offspring_sigma) {
  TimedEvaluator evaluator(settings, c);
  Archive archive(c.grid.cells, c.shape.param_count(), c.grid.dims());
  Dataset dataset(c.shape.param_count());
  SilentObserver observer;
  MapElites loop(settings, c, evaluator, archive, dataset, observer);
  loop.initial_sampling();

  EpisodePilot p;
  p.episodes = evaluator.episodes;
  p.seconds = evaluator.seconds;
  p.mean_steps = p.episodes > 0 ? evaluator.steps / static_cast<double>(p.episodes) : 0.0;
  p.max_steps = c.environment->info().max_steps;
  p.loop0_archive = archive.size();
  if (archive.size() == 0) return p;

  const auto n = static_cast<std::size_t>(settings.initial_samples);
  Parents parents;
  Rng selection(settings.seed, Stream::kSelection, 1, 0);
  archive.select(n, selection, parents);
  Matrix offspring = parents.theta;
  Rng mutation(settings.seed, Stream::kMutation, 1, 0);
  for (Eigen::Index r = 0; r < offspring.rows(); ++r)
    for (Eigen::Index j = 0; j < offspring.cols(); ++j) offspring(r, j) += offspring_sigma * mutation.normal();
  std::vector<std::uint64_t> seeds(n);
  for (std::size_t k = 0; k < n; ++k) seeds[k] = Rng::derive_seed(settings.seed, Stream::kEpisode, 1, 0, k);
  const double seconds = evaluator.seconds, steps = evaluator.steps;
  Evaluations evaluated;
  evaluator.evaluate(offspring, seeds, 0, evaluated);
  p.offspring_episodes = evaluator.episodes - p.episodes;
  p.offspring_seconds = evaluator.seconds - seconds;
  p.offspring_mean_steps =
      p.offspring_episodes > 0 ? (evaluator.steps - steps) / static_cast<double>(p.offspring_episodes) : 0.0;
  return p;
}

MeasuredRate measured_rate(std::istream& in, int iterations) {
  std::string line;
  if (!std::getline(in, line)) return {};
  std::vector<std::string> header;
  {
    std::stringstream ss(line);
    for (std::string name; std::getline(ss, name, ',');) header.push_back(name);
  }
  auto column = [&](const char* name) {
    const auto it = std::find(header.begin(), header.end(), name);
    return it == header.end() ? -1 : static_cast<int>(it - header.begin());
  };
  const int c_loop = column("loop"), c_it = column("iteration"), c_eval = column("evaluations"),
            c_wall = column("wall_seconds"), c_train = column("train_seconds");
  if (std::min({c_loop, c_it, c_eval, c_wall, c_train}) < 0) return {};

  std::map<int, std::vector<double>> per_loop;  // seconds per evaluation of each iteration
  MeasuredRate out;
  bool have_previous = false;
  double previous_work = 0.0, previous_evaluations = 0.0;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) cells.push_back(cell);
    if (static_cast<int>(cells.size()) < static_cast<int>(header.size()) - 1) continue;
    auto number = [&](int c) { return c < static_cast<int>(cells.size()) ? std::atof(cells[c].c_str()) : 0.0; };
    const int loop = std::atoi(cells[c_loop].c_str()), it = std::atoi(cells[c_it].c_str());
    const double work = number(c_wall) - number(c_train), evaluations = number(c_eval);
    if (have_previous && loop >= 1 && evaluations > previous_evaluations)
      per_loop[loop].push_back((work - previous_work) / (evaluations - previous_evaluations));
    if (loop >= 1 && it == iterations - 1) out.loop = std::max(out.loop, loop);
    previous_work = work;
    previous_evaluations = evaluations;
    have_previous = true;
  }
  if (out.loop < 1) return {};
  std::vector<double>& v = per_loop[out.loop];
  if (v.empty()) return {};
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  out.seconds_per_evaluation = std::max(0.0, v[v.size() / 2]);
  return out;
}

std::size_t expected_dataset_rows(const ExperimentSettings& s, const CostModel& cost, const EpisodePilot& pilot,
                                  std::int64_t cells, int loop) {
  const auto d0 = static_cast<double>(pilot.loop0_archive);
  // The fit after loop `loop` sees every cell found by its end.
  const double found = loop == 0            ? d0
                       : cost.cells.empty() ? d0 * (1.0 + kDatasetGrowth * std::sqrt(loop))
                                            : std::max(d0, cost.cells_at(loop_end_evaluations(s, loop)));
  return static_cast<std::size_t>(std::min(found, static_cast<double>(std::max<std::int64_t>(cells, 0))));
}

double loop_midpoint_evaluations(const ExperimentSettings& s, int loop) {
  const double per_loop = static_cast<double>(s.iterations) * s.batch;
  return s.initial_samples + (loop - 1) * per_loop + per_loop / 2;
}

double loop_end_evaluations(const ExperimentSettings& s, int loop) {
  return s.initial_samples + static_cast<double>(loop) * s.iterations * s.batch;
}

CostEstimate estimate_run_cost(const ExperimentSettings& s, const CostModel& cost, Components& c,
                               const EpisodePilot& pilot, int first_loop, MeasuredRate measured) {
  CostEstimate e;
  const bool own_rate = measured.seconds_per_evaluation > 0;
  // [cost], measured on long runs, states a breeding run's time per evaluation as a multiple of
  // loop 0's; without it, the pilot's offspring price those loops. A resumed run's own rate grows
  // as [cost] does from the loop it was measured in.
  const bool lengthens = c.mutator->uses_parents() && !cost.offspring_time.empty() && (!own_rate || measured.loop >= 1);
  auto factor = [&](int loop) { return cost.offspring_time_at(loop_midpoint_evaluations(s, loop)); };
  const double base_factor = own_rate && lengthens ? factor(measured.loop) : 1.0;
  const double later_base = own_rate                    ? measured.seconds_per_evaluation
                            : lengthens                 ? pilot.seconds_per_episode()
                            : c.mutator->uses_parents() ? pilot.offspring_seconds_per_episode()
                                                        : pilot.seconds_per_episode();
  auto seconds_per_evaluation = [&](int loop) {
    if (loop == 0 && !own_rate) return pilot.seconds_per_episode();
    return lengthens ? later_base * factor(loop) / base_factor : later_base;
  };
  if (lengthens) {
    e.lengthening.first_loop = std::max(first_loop, 1);
    e.lengthening.last_loop = s.loops - 1;
    e.lengthening.from = factor(e.lengthening.first_loop) / base_factor;
    e.lengthening.to = factor(e.lengthening.last_loop) / base_factor;
  }
  std::vector<std::size_t> rows;
  for (int loop = 0; loop < s.loops; ++loop) {
    const long long n = loop == 0 ? s.initial_samples : static_cast<long long>(s.iterations) * s.batch;
    if (loop >= first_loop) {
      e.evaluations += n;
      e.episode_seconds += static_cast<double>(n) * seconds_per_evaluation(loop);
    }
    rows.push_back(expected_dataset_rows(s, cost, pilot, c.grid.cells, loop));
  }
  e.dataset_rows_last = rows.empty() ? 0 : rows.back();
  e.dataset_rows_from_cost = !cost.cells.empty();
  // A representation that does not implement FitTimeEstimate costs nothing beyond the episodes.
  const auto* timing = dynamic_cast<const FitTimeEstimate*>(c.representation.get());
  if (c.representation->latent_size() == 0 || rows.empty() || !timing) return e;
  std::vector<double> fit;
  call_plugin(c.representation_label, "estimate_fit_seconds()", [&] { fit = timing->estimate_fit_seconds(rows); });
  if (fit.size() != rows.size())
    throw PluginError(c.representation_label + ": estimate_fit_seconds() returned " + std::to_string(fit.size()) +
                      " values for " + std::to_string(rows.size()) + " loops");
  for (std::size_t loop = static_cast<std::size_t>(std::max(first_loop, 0)); loop < fit.size(); ++loop) {
    if (!std::isfinite(fit[loop]) || fit[loop] < 0)
      throw PluginError(c.representation_label + ": estimate_fit_seconds() returned " + std::to_string(fit[loop]) +
                        " for loop " + std::to_string(loop) + " (expected finite seconds >= 0)");
    e.training_seconds += fit[loop];
  }
  return e;
}

}  // namespace qd::runtime
