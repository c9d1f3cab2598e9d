// The training dataset D of the representation (the paper, Sec. 3).
//
// Reference semantics: one policy per behaviour cell ever discovered, namely the archive occupant
// at the end of the loop in which the cell was first filled; later replacements in the archive are
// not copied here. Entries are kept in insertion order (oldest first), which the reference
// train/test split relies on. The core maintains D; representations only read it.
#pragma once

#include <qd/export.hpp>
#include <qd/types.hpp>

#include <Eigen/Core>

#include <cstdint>
#include <unordered_set>
#include <vector>

namespace qd {

class QD_EXPORT Dataset {
 public:
  explicit Dataset(std::size_t param_count = 0);

  std::size_t size() const noexcept { return cells_.size(); }
  std::size_t param_count() const noexcept { return param_count_; }
  bool contains_cell(std::int64_t cell) const { return cell_set_.count(cell) != 0; }

  void add(const double* theta, std::int64_t cell, int loop);

  // N × P, storage order.
  Eigen::Map<const Matrix> params() const {
    return Eigen::Map<const Matrix>(params_.data(), static_cast<Eigen::Index>(size()),
                                    static_cast<Eigen::Index>(param_count_));
  }
  const std::vector<std::int64_t>& cells() const noexcept { return cells_; }
  const std::vector<int>& loops() const noexcept { return loops_; }

 private:
  std::size_t param_count_;
  std::vector<double> params_;
  std::vector<std::int64_t> cells_;
  std::vector<int> loops_;
  std::unordered_set<std::int64_t> cell_set_;
};

}  // namespace qd
