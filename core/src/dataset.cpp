#include <qd/dataset.hpp>
#include <qd/errors.hpp>

namespace qd {

Dataset::Dataset(std::size_t param_count) : param_count_(param_count) {}

void Dataset::add(const double* theta, std::int64_t cell, int loop) {
  QD_CHECK(!contains_cell(cell), "dataset holds one policy per cell");
  params_.insert(params_.end(), theta, theta + param_count_);
  cells_.push_back(cell);
  loops_.push_back(loop);
  cell_set_.insert(cell);
}

}  // namespace qd
