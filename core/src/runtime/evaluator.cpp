#include "runtime/evaluator.hpp"

#include <thread>

namespace qd::runtime {

Evaluator::~Evaluator() = default;

void Evaluations::reset(std::size_t n, std::size_t dims) {
  status.assign(n, EvalStatus::kOk);
  steps.assign(n, 0);
  fitness.assign(n, 0.0);
  cells.assign(n, -1);
  descriptors.setZero(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(dims));
}

int hardware_workers() {
  const unsigned n = std::thread::hardware_concurrency();
  return n == 0 ? 1 : static_cast<int>(n);
}

}  // namespace qd::runtime
