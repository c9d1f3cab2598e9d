// The planning wing's part of an experiment file: [cost], what `qdrun --dry-run` assumes about an
// environment beyond what its pilot measures (cost_estimate.hpp). It changes no result, so it is
// no part of a run's configuration: resolve() checks it (a typo there is found before hours of
// running) but leaves it out of ExperimentSettings and of the resolved config.toml, and a run may
// be resumed or swept under a file that changed it.
#pragma once

#include "runtime/config_document.hpp"
#include "runtime/config_schema.hpp"

#include <vector>

namespace qd::runtime {

struct CostModel {
  // Wall time per evaluation of a mutation operator as a multiple of loop 0's, once
  // `evaluations[i]` evaluations are done: linear in between, the end values held outside; 1 when
  // empty. Episodes lengthen as an archive reaches cells that only long episodes reach; qdreport
  // measures this from finished runs ("Episode lengthening").
  std::vector<double> evaluations, offspring_time;
  // Distinct cells found once `evaluations[i]` evaluations are done, linear in between, the end
  // values held; empty when not given. A representation trains on one policy per cell ever found,
  // so this sizes its dataset; how far an archive spreads depends on the algorithm and the
  // environment, which no pilot of loop 0 can see (qdreport measures it with offspring_time).
  std::vector<double> cells;
  double offspring_time_at(double evaluations_done) const;
  double cells_at(double evaluations_done) const;
};

// [cost] of `doc`, checked (unknown keys, ranges, one time per entry, increasing evaluations);
// throws qd::InputError naming file, line and key.
CostModel read_cost_model(const Document& doc);

// [cost]'s parameters, for --describe (core_tables()).
CoreTable cost_table();

}  // namespace qd::runtime
