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
                   "evaluations done (increasing) at which offspring_time is given; --dry-run only"),
    param_float_list("offspring_time", "[]", 0.01, 1000,
                     "time per evaluation of a mutation operator at each of `evaluations`, as a multiple of loop "
                     "0's (linear in between, end values held; [] = the dry-run pilot's offspring throughout; "
                     "qdreport measures it from finished runs); --dry-run only, no result depends on it"),
};
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
  if (m.evaluations.size() != m.offspring_time.size())
    throw InputError(cost.where("offspring_time") + ": cost.offspring_time has " +
                     std::to_string(m.offspring_time.size()) + " values for " + std::to_string(m.evaluations.size()) +
                     " cost.evaluations; give one per entry");
  for (std::size_t i = 1; i < m.evaluations.size(); ++i)
    if (m.evaluations[i] <= m.evaluations[i - 1])
      throw InputError(cost.where("evaluations") + ": cost.evaluations must increase (entry " + std::to_string(i + 1) +
                       " is not above entry " + std::to_string(i) + ")");

  return m;
}

double CostModel::offspring_time_at(double n) const {
  if (evaluations.empty()) return 1.0;
  if (n <= evaluations.front()) return offspring_time.front();
  for (std::size_t i = 1; i < evaluations.size(); ++i)
    if (n <= evaluations[i]) {
      const double t = (n - evaluations[i - 1]) / (evaluations[i] - evaluations[i - 1]);
      return offspring_time[i - 1] + t * (offspring_time[i] - offspring_time[i - 1]);
    }
  return offspring_time.back();
}

}  // namespace qd::runtime
