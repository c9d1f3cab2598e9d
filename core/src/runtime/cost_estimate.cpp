#include "runtime/cost_estimate.hpp"

#include "runtime/archive.hpp"
#include "runtime/evaluator.hpp"
#include "runtime/map_elites.hpp"
#include "runtime/plugin_output_checks.hpp"

#include <qd/dataset.hpp>
#include <qd/errors.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>

namespace qd::runtime {
namespace {

// One supervised worker process (a crash or hang in plugin code is reported naming it, as in a
// run), timed, counting world steps.
class TimedEvaluator final : public Evaluator {
 public:
  TimedEvaluator(const ExperimentSettings& s, const Components& c) {
    EvaluatorSpec spec;
    spec.backend = "processes";
    spec.workers = 1;
    spec.capacity = static_cast<std::size_t>(s.initial_samples);
    spec.timeout_seconds = s.timeout_seconds;
    spec.labels = {c.environment_label, c.descriptor_label};
    inner_ = make_evaluator(spec, *c.environment, *c.descriptor, c.shape);
  }
  int workers() const noexcept override { return 1; }
  const char* backend() const noexcept override { return inner_->backend(); }
  void evaluate(const Matrix& params, const std::vector<std::uint64_t>& seeds, Evaluations& out) override {
    const auto start = std::chrono::steady_clock::now();
    inner_->evaluate(params, seeds, out);
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
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

EpisodePilot run_episode_pilot(const ExperimentSettings& settings, Components& c) {
  TimedEvaluator evaluator(settings, c);
  Archive archive(c.grid.cells, c.shape.param_count(), c.grid.shape.size());
  Dataset dataset(c.shape.param_count());
  SilentObserver observer;
  MapElites loop(settings, c, evaluator, archive, dataset, observer, "");
  loop.initial_sampling();

  EpisodePilot p;
  p.episodes = evaluator.episodes;
  p.seconds = evaluator.seconds;
  p.mean_steps = p.episodes > 0 ? evaluator.steps / static_cast<double>(p.episodes) : 0.0;
  p.max_steps = c.environment->info().max_steps;
  p.loop0_archive = archive.size();
  return p;
}

std::size_t expected_dataset_rows(const EpisodePilot& pilot, std::int64_t cells, int loop) {
  const double rows = static_cast<double>(pilot.loop0_archive) * (1.0 + kDatasetGrowth * std::sqrt(loop));
  return static_cast<std::size_t>(std::min(rows, static_cast<double>(std::max<std::int64_t>(cells, 0))));
}

CostEstimate estimate_run_cost(const ExperimentSettings& s, Components& c, const EpisodePilot& pilot, int first_loop) {
  CostEstimate e;
  const double per_step = pilot.seconds_per_step();
  const double s0 = pilot.mean_steps;
  const double later_steps =
      c.mutator->uses_parents() ? s0 + kEpisodeGrowth * std::max(0.0, static_cast<double>(pilot.max_steps) - s0) : s0;
  std::vector<std::size_t> rows;
  for (int loop = 0; loop < s.loops; ++loop) {
    const long long n = loop == 0 ? s.initial_samples : static_cast<long long>(s.iterations) * s.batch;
    if (loop >= first_loop) {
      e.evaluations += n;
      e.episode_seconds += static_cast<double>(n) * per_step * (loop == 0 ? s0 : later_steps);
    }
    rows.push_back(expected_dataset_rows(pilot, c.grid.cells, loop));
  }
  if (c.representation->latent_size() == 0 || rows.empty()) return e;
  std::vector<double> fit;
  call_plugin(c.representation_label, "estimate_fit_seconds()",
              [&] { fit = c.representation->estimate_fit_seconds(rows); });
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
