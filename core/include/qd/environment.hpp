// Environment: runs policies and returns their traces.
//
// Contract
//  * Stateless between rollouts: the same policy parameters (and episode seed) give the same
//    trace whatever worker, thread or order runs them. rollout() is const and must be safe to call
//    concurrently from several threads on disjoint index ranges.
//  * Expected per-episode failures (NaN action, diverged physics) are status values in the Trace,
//    never exceptions. An exception from rollout() is a bug and ends the run.
//  * One virtual call per batch range: the evaluator hands each worker a range of rows.
//  * What rollout() receives: traces[i] for i in [begin, end) as left by Trace::clear() (status
//    kOk, steps 0, fitness 0, events and message empty, main and aux without rows). Trace objects
//    are reused from batch to batch, so main.cols and aux.cols may still hold an earlier rollout's
//    column count: call main.reset(cols) (and aux.reset) before pushing rows. Rows outside
//    [begin, end) belong to other workers and must not be touched.
//  * What rollout() gives back: status, steps, main/aux/events for the descriptor, and fitness,
//    where higher is better. Fitness decides only under [experiment] insertion = "fitness" (an
//    offspring replaces an occupant when its fitness is strictly higher) and is written to
//    archive.csv's objective column; the paper's coin-flip insertion ignores it. It must be finite.
//    info().has_fitness says whether it means anything (the QD metrics of metrics.csv need it).
//  * Persistent worlds, the one exception to statelessness (info().persistent_worlds = N > 0): the
//    environment keeps N worlds whose state carries from one episode to the next (to emulate a
//    reference implementation that reuses one simulator per worker process). The core runs episode
//    e of the run (counted from 0 over the whole run, loop 0 included) in world e mod N, one row
//    per call with batch.world set, the episodes of a world in order and never two calls for the
//    same world at once; calls for different worlds may run concurrently. Such environments run
//    in qdrun's own process (backend "threads"). Their worlds are saved with every checkpoint
//    (save()) and the run then continues from what load() rebuilds of that save, so an
//    uninterrupted run and a resumed one go the same way even when a world cannot be restored bit
//    for bit. Calls with world = -1 (replays, the dry-run's pilot) run in a fresh world and must
//    leave the persistent ones untouched.
#pragma once

#include <qd/component.hpp>
#include <qd/export.hpp>
#include <qd/policy.hpp>
#include <qd/types.hpp>

#include <cstdint>
#include <limits>
#include <ostream>
#include <string>

namespace qd {

struct EnvironmentInfo {
  int observation_size = 0;
  int action_size = 0;
  int max_steps = 0;
  // (The default descriptor is declared with the component: qd::environment<T>, <qd/plugin.hpp>.)
  int persistent_worlds = 0;  // 0: stateless (the contract above); N > 0: N persistent worlds
  // Whether Trace::fitness is the task's objective. Without one (the PoMS paper's Box2D tasks), the
  // QD metrics of metrics.csv (qd_score, max_fitness, mean_fitness) stay empty and
  // [experiment] insertion = "fitness" is refused.
  bool has_fitness = false;
  // The lowest fitness the task can give: qd_score = sum over the elites of (fitness - this bound),
  // comparable across runs. NaN = not declared ([experiment] fitness_lower_bound may give it;
  // without either, qd_score stays empty while max_fitness and mean_fitness are written).
  double fitness_lower_bound = std::numeric_limits<double>::quiet_NaN();
  // > 0: the environment evaluates plain parameter vectors of this length (a direct encoding, as the
  // standard QD benchmarks do) instead of policy networks; observation_size, action_size and
  // [policy] do not apply, and batch.shape->is_direct() is true.
  int parameters = 0;
};

// A batch of rollouts: rows [begin, end) of `params`, each with its own episode seed.
//  * `params` is row-major with shape->param_count() doubles per row: row i, the policy of
//    traces[i], starts at params + i * shape->param_count() (row(i)). A plain pointer, not a
//    Matrix, so worker processes hand over the rows where they already are (shared memory) without
//    copying them.
//  * Only rows (and seeds) i in [begin, end) may be read; the array may belong to a larger batch.
//  * The memory is read-only and valid only for the duration of the rollout() call: copy what must
//    outlive it.
//  * traces[i] for i in [begin, end) arrive cleared (see the contract above).
struct RolloutBatch {
  const PolicyShape* shape = nullptr;
  const double* params = nullptr;                // N × P, row-major (P = shape->param_count())
  const std::uint64_t* episode_seeds = nullptr;  // N seeds (deterministic environments ignore them)
  std::size_t begin = 0;
  std::size_t end = 0;
  // -1: a stateless rollout. Otherwise (environments with persistent worlds only) the world that the
  // single row [begin, begin + 1) runs in, 0 <= world < info().persistent_worlds.
  int world = -1;

  // The parameters of row i (P doubles).
  const double* row(std::size_t i) const noexcept { return params + i * shape->param_count(); }
};

class QD_EXPORT Environment : public Component {
 public:
  ~Environment() override;

  virtual EnvironmentInfo info() const = 0;

  // Fills traces[i] for every i in [batch.begin, batch.end) from batch.row(i): `traces` is indexed
  // like the rows of batch.params (it points at the whole batch's array, not at traces[begin]).
  // Thread-safe.
  virtual void rollout(const RolloutBatch& batch, Trace* traces) const = 0;

  // Draws the scene and one rollout's trace as a standalone SVG document. Returns false when the
  // environment cannot draw.
  virtual bool draw_svg(const Trace& trace, std::ostream& out) const;

  // Environments with persistent worlds only: the state of every world, for the checkpoint, and
  // the worlds rebuilt from such a state (throw on a malformed one). The defaults do nothing.
  virtual void save(std::ostream& out) const;
  virtual void load(std::istream& in);
};

}  // namespace qd
