// [cost] (cost_model.hpp): the dry-run's cost table, read and checked apart from the run's settings.
#include "runtime/cost_model.hpp"
#include "runtime/config_toml.hpp"

#include <qd/errors.hpp>

#include <iterator>

namespace qd::runtime {

namespace {
constexpr double kMaxInt = 9.0e15;
const ParamSpec kCostParams[] = {
    param_int_list("evaluations", "[]", 0, kMaxInt,
                   "evaluations done (increasing) at which offspring_time and cells are given; --dry-run only"),
    param_float_list("offspring_time", "[]", 0.01, 1000,
                     "time per evaluation of a mutation operator at each of `evaluations`, as a multiple of loop "
                     "0's (linear in between, end values held; [] = the dry-run pilot's offspring throughout; "
                     "qdreport measures it from finished runs); --dry-run only, no result depends on it"),
    param_int_list("cells", "[]", 0, kMaxInt,
                   "distinct cells found at each of `evaluations`, the dataset a representation trains on (linear "
                   "in between, end values held; [] = loop 0's archive grown by 1 + 1.2 sqrt(loop); qdreport "
                   "measures it from finished runs); --dry-run only, no result depends on it"),
};

// `values` (cost.`key`) gives one number per cost.evaluations, or none.
void check_length(const Config& cost, const char* key, std::size_t values, std::size_t evaluations) {
  if (values != 0 && values != evaluations)
    throw InputError(cost.where(key) + ": cost." + key + " has " + std::to_string(values) + " values for " +
                     std::to_string(evaluations) + " cost.evaluations; give one per entry");
}

// Linear in `x` between the entries of y, the end values held outside; `empty` without a table.
double interpolate(const std::vector<double>& x, const std::vector<double>& y, double at, double empty) {
  if (y.empty()) return empty;
  if (at <= x.front()) return y.front();
  for (std::size_t i = 1; i < x.size(); ++i)
    if (at <= x[i]) {
      const double t = (at - x[i - 1]) / (x[i] - x[i - 1]);
      return y[i - 1] + t * (y[i] - y[i - 1]);
    }
  return y.back();
}
}  // namespace

CoreTable cost_table() {
  return {"cost", kCostParams, std::size(kCostParams)};
}

CostModel read_cost_model(const Document& doc) {
  CostModel m;
  const Config cost =
      validate_table(sub_table(doc.impl->root, "cost"), "cost", kCostParams, std::size(kCostParams), "the core");
  for (auto n : cost.get_int_list("evaluations")) m.evaluations.push_back(static_cast<double>(n));
  m.offspring_time = cost.get_float_list("offspring_time");
  for (auto n : cost.get_int_list("cells")) m.cells.push_back(static_cast<double>(n));
  check_length(cost, "offspring_time", m.offspring_time.size(), m.evaluations.size());
  check_length(cost, "cells", m.cells.size(), m.evaluations.size());
  if (!m.evaluations.empty() && m.offspring_time.empty() && m.cells.empty())
    throw InputError(cost.where("evaluations") +
                     ": cost.evaluations needs a table to index: give cost.offspring_time, cost.cells or both");
  for (std::size_t i = 1; i < m.evaluations.size(); ++i)
    if (m.evaluations[i] <= m.evaluations[i - 1])
      throw InputError(cost.where("evaluations") + ": cost.evaluations must increase (entry " + std::to_string(i + 1) +
                       " is not above entry " + std::to_string(i) + ")");

  return m;
}

double CostModel::offspring_time_at(double n) const {
  return interpolate(evaluations, offspring_time, n, 1.0);
}

double CostModel::cells_at(double n) const {
  return interpolate(evaluations, cells, n, 0.0);
}

}  // namespace qd::runtime
