// Mutator: makes a batch of offspring (MAP-Elites variation operators and fresh-sample samplers).
//
// Contract
//  * Called on the main thread, once per iteration, in a fixed order:
//      begin_loop (once per loop n >= 1)  ->  [mutate -> feedback] × iterations.
//    Loop 0 calls only mutate(), with empty parents, on the experiment's [initial] mutator.
//  * All randomness comes from ctx.rng, which the core derives from (seed, loop, iteration).
//  * What mutate() receives: `out` already sized by Offspring::reset(count, P, LD): theta is
//    count × P and latent count × LD (0 × 0 without a latent space), both with unspecified values;
//    has_latent is count zeros, mixing_ratio NaN, metrics empty. `parents` holds `count` rows
//    selected uniformly from the archive (without replacement once it holds `count` elites), or
//    none at all for samplers and in loop 0.
//  * mutate() fills every row of out.theta (assigning a new count × P matrix is fine). When the
//    representation has a latent space, a mutator may give the latent point each offspring came
//    from (out.latent row + has_latent = 1); the core encodes the others and stores
//    recn_error = ‖θ′ − Dec(z′)‖ (docs/reference-behaviour.md). It appends one value per
//    metric_names() entry to out.metrics. Another shape is an error that ends the run.
//  * Mutators whose uses_parents() is false (samplers: ps-uniform, ps-glorot) get no parents.
//  * State that must survive a checkpoint (the DDE bandit) goes through save()/load().
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

// Selected parents: copies of the elites' rows.
struct Parents {
  Matrix theta;       // n × P
  Vector recn_error;  // stored reconstruction errors (0 without a model)
  std::vector<std::int64_t> cells;
};

// What the archive did with one offspring.
enum class Insertion : std::uint8_t { kAdded = 0, kReplaced = 1, kRejected = 2, kInvalid = 3 };

struct QD_EXPORT Offspring {
  Matrix theta;                          // count × P
  Matrix latent;                         // count × LD (only when LD > 0)
  std::vector<std::uint8_t> has_latent;  // 1 where latent.row(i) is the offspring's origin z′
  // Fraction of this batch made in parameter space (the reference "mixing ratio"); NaN = not
  // applicable (written as an empty CSV field).
  double mixing_ratio = std::numeric_limits<double>::quiet_NaN();
  // Extra per-iteration values, in the order of Mutator::metric_names().
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

// What happened to the last batch, for adaptive operators.
struct Feedback {
  int loop = 0;
  int iteration = 0;
  std::size_t offspring = 0;
  std::size_t added = 0;     // new cells
  std::size_t replaced = 0;  // occupants replaced
  std::size_t rejected = 0;
  std::size_t invalid = 0;                           // failed evaluations or undescribable traces
  const std::vector<Insertion>* outcomes = nullptr;  // one per offspring, in order
};

class QD_EXPORT Mutator : public Component {
 public:
  ~Mutator() override;

  virtual bool uses_parents() const noexcept { return true; }
  // Whether this operator needs a representation with a latent space (checked at setup).
  virtual bool needs_latent() const noexcept { return false; }
  // Names of Offspring::metrics columns added to metrics.csv (e.g. the DDE arm).
  virtual std::vector<std::string> metric_names() const { return {}; }

  virtual void begin_loop(const LoopContext& ctx);
  virtual void mutate(const Parents& parents, std::size_t count, MutateContext& ctx, Offspring& out) = 0;
  virtual void feedback(const Feedback& fb);

  virtual void save(std::ostream& out) const;
  virtual void load(std::istream& in);
};

}  // namespace qd
