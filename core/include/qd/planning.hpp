// Planning: what a component may tell `qdrun --dry-run` about its own cost, apart from its
// contract. Nothing here takes part in a run; the core asks for it only on objects built for an
// estimate (runtime/cost_estimate.hpp), and a component that implements none of it is priced as
// costing nothing beyond the episodes.
#pragma once

#include <qd/export.hpp>

#include <cstddef>
#include <vector>

namespace qd {

// A representation whose fit() costs enough to matter next to the episodes (a network trained for
// many epochs) implements this beside Representation:
//   class MyModel final : public qd::Representation, public qd::FitTimeEstimate { ... };
class QD_EXPORT FitTimeEstimate {
 public:
  virtual ~FitTimeEstimate();

  // Estimated seconds of fit() on one core, one value per loop: rows[l] is the size of D at loop
  // l's fit (l = 0, 1, ...). Measure (time a little training on random data of the run's shape)
  // rather than guess. It must not change what this object computes.
  virtual std::vector<double> estimate_fit_seconds(const std::vector<std::size_t>& rows) const = 0;
};

}  // namespace qd
