// Mutator: makes a batch of offspring (MAP-Elites variation operators and fresh-sample samplers).
//
// Contract
//  * Called on the main thread, once per iteration, in a fixed order:
//      begin_loop (once per loop n >= 1)  ->  [mutate -> feedback] × iterations.
//    Loop 0 calls only mutate(), with empty parents, on the experiment's [initial] mutator.
//  * All randomness comes from ctx.rng, which the core derives from (seed, loop, iteration).
//  * What mutate() receives: `out` already sized by Offspring::reset(count, P, LD): theta is
//    count × P and latent count × LD (0 × 0 without a latent space), both with unspecified values;
//    has_latent is count zeros, metrics empty. `parents` holds `count` rows
//    selected uniformly from the archive (without replacement once it holds `count` elites), or
//    none at all for samplers and in loop 0.
//  * mutate() fills every row of out.theta (assigning a new count × P matrix is fine). When the
//    representation has a latent space, a mutator may give the latent point each offspring came
//    from (out.latent row + has_latent = 1); the core encodes the others and stores
//    recn_error = ‖θ′ − Dec(z′)‖ (docs/reference-behaviour.md). It appends one value per
//    metric_names() entry to out.metrics. Another shape is an error that ends the run. A metric
//    named kMixingRatio (the share of the batch made in parameter space, in [0, 1]) fills
//    metrics.csv's mixing_ratio column; the others get columns of their own.
//  * Mutators whose uses_parents() is false (samplers: ps-uniform, ps-glorot) get no parents.
//  * feedback() tells, per offspring in batch order, what the archive did with it and the fitness
//    it brought (Feedback::results): what adaptive operators such as CMA-ME's emitters rank by.
//  * State that must survive a checkpoint (the DDE bandit, CMA-ES) goes through save()/load().
#pragma once

#include <qd/archive.hpp>
#include <qd/component.hpp>
#include <qd/dataset.hpp>
#include <qd/export.hpp>
#include <qd/representation.hpp>
#include <qd/rng.hpp>
#include <qd/types.hpp>

#include <cstdint>
#include <iosfwd>
#include <limits>
#include <string>
#include <vector>

namespace qd {

// The metric name of the fraction of a batch made in parameter space (the reference's "mixing
// ratio"): metrics.csv writes it in its mixing_ratio column, empty for mutators without it.
inline constexpr const char* kMixingRatio = "mixing_ratio";

// Selected parents: copies of the elites' rows.
struct Parents {
  Matrix theta;       // n × P
  Vector recn_error;  // stored reconstruction errors (0 without a model)
  std::vector<std::int64_t> cells;
};

struct QD_EXPORT Offspring {
  Matrix theta;                          // count × P
  Matrix latent;                         // count × LD (only when LD > 0)
  std::vector<std::uint8_t> has_latent;  // 1 where latent.row(i) is the offspring's origin z′
  // Per-iteration values, in the order of Mutator::metric_names().
  std::vector<double> metrics;

  void reset(std::size_t count, std::size_t params, std::size_t latent_size);
};

struct LoopContext {
  int loop = 0;
  const ArchiveView* archive = nullptr;
  const Dataset* dataset = nullptr;
  const Representation* representation = nullptr;
};

struct MutateContext {
  int loop = 0;
  int iteration = 0;
  Rng* rng = nullptr;
  const Representation* representation = nullptr;  // never null; latent_size() may be 0
  const ArchiveView* archive = nullptr;            // never null
};

// What became of one offspring.
enum class Outcome : std::uint8_t {
  kNewCell = 0,    // it filled an empty cell
  kImproved = 1,   // it replaced an occupant of strictly lower fitness
  kReplaced = 2,   // it replaced an occupant it is not fitter than (coin-flip insertion)
  kDiscarded = 3,  // the occupant stayed
  kInvalid = 4,    // a failed evaluation or an undescribable trace: never offered
};
QD_EXPORT const char* to_string(Outcome outcome) noexcept;

struct OffspringResult {
  Outcome outcome = Outcome::kInvalid;
  std::int64_t cell = -1;                                     // -1 when invalid
  double fitness = std::numeric_limits<double>::quiet_NaN();  // the offspring's; NaN when invalid
  // The occupant's fitness just before this offspring was offered (insertion is sequential in
  // batch order); NaN when the cell was empty or the offspring invalid.
  double previous = std::numeric_limits<double>::quiet_NaN();

  // Whether it is in the archive now (new cell, improved or replaced).
  bool entered() const noexcept {
    return outcome == Outcome::kNewCell || outcome == Outcome::kImproved || outcome == Outcome::kReplaced;
  }
  // The fitness change it brings to its cell: fitness - previous for an occupied cell (negative when
  // it was not fitter), the fitness itself for a new cell (as the CMA-ME paper and pyribs rank), NaN
  // when invalid.
  double change() const noexcept { return outcome == Outcome::kNewCell ? fitness : fitness - previous; }
};

// What happened to the last batch, for adaptive operators.
struct Feedback {
  int loop = 0;
  int iteration = 0;
  std::size_t offspring = 0;
  std::size_t added = 0;                                  // new cells
  std::size_t replaced = 0;                               // occupants replaced (improved or not)
  std::size_t rejected = 0;                               // discarded
  std::size_t invalid = 0;                                // failed evaluations or undescribable traces
  const std::vector<OffspringResult>* results = nullptr;  // one per offspring, in batch order
};

class QD_EXPORT Mutator : public Component {
 public:
  ~Mutator() override;

  virtual bool uses_parents() const noexcept { return true; }
  // Whether this operator needs a representation with a latent space (checked at setup).
  virtual bool needs_latent() const noexcept { return false; }
  // Names of the Offspring::metrics values, each a metrics.csv column (e.g. the DDE arm;
  // kMixingRatio fills the mixing_ratio column).
  virtual std::vector<std::string> metric_names() const { return {}; }

  virtual void begin_loop(const LoopContext& ctx);
  virtual void mutate(const Parents& parents, std::size_t count, MutateContext& ctx, Offspring& out) = 0;
  virtual void feedback(const Feedback& fb);

  virtual void save(std::ostream& out) const;
  virtual void load(std::istream& in);
};

}  // namespace qd
