// CMA-ME, the mutator "cma-me" (Fontaine, Togelius, Nikolaidis, Hoover, "Covariance Matrix
// Adaptation for the Rapid Illumination of Behavior Space", GECCO 2020): `emitters` improvement
// emitters, each a CMA-ES (cma_es.hpp) with its own mean, step size and covariance, share the
// batch; emitter e makes offspring rows [e lambda, (e + 1) lambda), lambda = batch / emitters.
//
// After the archive has taken the batch (feedback()), each emitter ranks its offspring as the
// paper's improvement emitter does: those that filled a new cell first, by fitness; then those that
// entered an occupied cell (improved it, or replaced it under the coin-flip rule), by the fitness
// change; then the rest, by the (negative) change. Its CMA-ES is updated with the offspring that
// entered the archive ("filter" selection, the paper's) or with the best lambda / 2 ("mu"), and it
// restarts, from a uniformly drawn elite (the core's selected parent of its index), when none of
// its offspring entered the archive ("no-improvement", the paper's), or only when its CMA-ES has
// converged ("basic"); in both cases also when the CMA-ES has converged or the ranking is flat.
// A restart takes effect at the next mutate(), whose parents are fresh elites; at the first
// mutate() of a run every emitter starts at its parent.
#pragma once

#include "cma_es.hpp"

#include <qd/component.hpp>
#include <qd/config.hpp>
#include <qd/mutator.hpp>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace qd::cma_me {

inline constexpr ParamSpec kCmaMeParams[] = {
    param_int("emitters", "15", 1, 100000,
              "number of improvement emitters; each makes batch / emitters offspring per iteration (the paper: 15 of "
              "37)"),
    param_float("sigma0", "0.5", 1e-12, kUnbounded, "initial step size of every emitter's CMA-ES (the paper: 0.5)"),
    param_string("selection", "\"filter\"", "filter|mu",
                 "filter = the offspring that entered the archive update the CMA-ES (the paper); mu = the best "
                 "lambda / 2 of the ranking (pyribs's cma_me_imp_mu)"),
    param_string("restart", "\"no-improvement\"", "no-improvement|basic",
                 "no-improvement = restart an emitter none of whose offspring entered the archive (the paper); "
                 "basic = only when its CMA-ES has converged"),
};

// Offspring k of a generation: the rank key of the improvement emitter. Higher ranks first.
struct RankKey {
  int stage;      // 2 = new cell, 1 = entered an occupied cell, 0 = the rest
  double value;   // fitness (new cell) or fitness change; -inf for an invalid evaluation
  std::size_t k;  // batch index (ties keep batch order)
};
// The improvement emitter's order of one emitter's results (indices into `results`, best first).
std::vector<std::size_t> improvement_ranking(const std::vector<OffspringResult>& results, std::size_t begin,
                                             std::size_t end);

class CmaMeMutator final : public Mutator {
 public:
  CmaMeMutator(const Config& cfg, const BuildContext& ctx);

  std::vector<std::string> metric_names() const override { return {"restarts", "sigma"}; }
  void mutate(const Parents& parents, std::size_t count, MutateContext& ctx, Offspring& out) override;
  void feedback(const Feedback& fb) override;
  void save(std::ostream& out) const override;
  void load(std::istream& in) override;

  // For tests.
  const CmaEs& emitter(std::size_t e) const { return *emitters_.at(e).es; }
  std::uint64_t restarts() const noexcept { return restarts_; }

 private:
  struct Emitter {
    std::unique_ptr<CmaEs> es;
    bool restart_pending = true;  // start (or restart) at the next mutate()'s parent
  };
  void start(std::size_t count, std::size_t params);

  std::size_t emitter_count_, lambda_ = 0, params_ = 0;
  double sigma0_;
  bool filter_, restart_on_no_improvement_;
  std::vector<Emitter> emitters_;
  std::uint64_t restarts_ = 0;
  Matrix samples_;  // the last mutate()'s offspring, for feedback()
};

}  // namespace qd::cma_me
