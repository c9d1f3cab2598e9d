#include "runtime/grid_archive.hpp"

#include <qd/errors.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

namespace qd::runtime {

Archive::Archive(std::int64_t cells, std::size_t param_count, std::size_t descriptor_dims)
    : cells_(cells),
      param_count_(param_count),
      dims_(descriptor_dims),
      cell_slot_(static_cast<std::size_t>(cells), -1) {
  QD_CHECK(cells > 0, "archive needs at least one cell");
  // Address space for every cell's parameters when that is modest (pages are only backed once
  // written), so a growing archive never copies its parameters.
  constexpr std::size_t kMaxReservedBytes = std::size_t{2} << 30;
  const auto n = static_cast<std::size_t>(cells);
  if (param_count > 0 && n <= kMaxReservedBytes / sizeof(double) / param_count) params_.reserve(n * param_count);
}

void Archive::mark_dirty(std::size_t slot) {
  if (!dirty_[slot]) {
    dirty_[slot] = 1;
    dirty_slots_.push_back(slot);
  }
}

Insertion Archive::offer(std::int64_t cell, const double* params, const double* descriptor, double fitness,
                         double recn_error, bool replace) {
  QD_CHECK(cell >= 0 && cell < cells_, "cell index out of range (checked where descriptors return it)");
  std::int64_t slot = cell_slot_[static_cast<std::size_t>(cell)];
  Insertion result = Insertion::kReplaced;
  if (slot < 0) {
    slot = static_cast<std::int64_t>(slot_cell_.size());
    cell_slot_[static_cast<std::size_t>(cell)] = slot;
    slot_cell_.push_back(cell);
    params_.resize(params_.size() + param_count_);
    desc_.resize(desc_.size() + dims_);
    fitness_.push_back(0.0);
    recn_.push_back(0.0);
    dirty_.push_back(0);
    result = Insertion::kAdded;
  } else if (!replace) {
    return Insertion::kRejected;
  }
  const auto s = static_cast<std::size_t>(slot);
  std::copy(params, params + param_count_, params_.begin() + static_cast<std::ptrdiff_t>(s * param_count_));
  std::copy(descriptor, descriptor + dims_, desc_.begin() + static_cast<std::ptrdiff_t>(s * dims_));
  fitness_[s] = fitness;
  recn_[s] = recn_error;
  mark_dirty(s);
  return result;
}

void Archive::set_recn_error(std::size_t slot, double error) {
  recn_[slot] = error;
  mark_dirty(slot);
}

void Archive::select(std::size_t n, Rng& rng, Parents& out) const {
  const std::size_t m = size();
  QD_CHECK(m > 0, "cannot select from an empty archive");
  std::vector<std::size_t> slots(n);
  if (m >= n) {
    // Partial Fisher-Yates: the first n entries of a uniform random permutation of the slots.
    std::vector<std::size_t> perm(m);
    std::iota(perm.begin(), perm.end(), std::size_t{0});
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t j = i + static_cast<std::size_t>(rng.below(m - i));
      std::swap(perm[i], perm[j]);
      slots[i] = perm[i];
    }
  } else {
    for (std::size_t i = 0; i < n; ++i) slots[i] = static_cast<std::size_t>(rng.below(m));
  }
  out.theta.resize(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(param_count_));
  out.recn_error.resize(static_cast<Eigen::Index>(n));
  out.cells.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t s = slots[i];
    std::copy(params(s), params(s) + param_count_, out.theta.row(static_cast<Eigen::Index>(i)).data());
    out.recn_error[static_cast<Eigen::Index>(i)] = recn_[s];
    out.cells[i] = slot_cell_[s];
  }
}

void Archive::take_dirty(std::vector<std::size_t>& slots) {
  slots.swap(dirty_slots_);
  dirty_slots_.clear();
  for (std::size_t s : slots) dirty_[s] = 0;
}

void Archive::restore(std::size_t slot, std::int64_t cell, const double* params, const double* descriptor,
                      double fitness, double recn_error) {
  if (cell < 0 || cell >= cells_) throw StateError("archive record has an invalid cell index");
  const bool appends = slot == size() && cell_slot_[static_cast<std::size_t>(cell)] < 0;
  const bool overwrites = slot < size() && slot_cell_[slot] == cell;
  if (!appends && !overwrites)
    throw StateError("archive record does not fit the archive (slot " + std::to_string(slot) + ", cell " +
                     std::to_string(cell) + ")");
  const bool was_dirty = overwrites && dirty_[slot];
  offer(cell, params, descriptor, fitness, recn_error, true);
  if (!was_dirty) {  // offer() just marked it, so it is the last dirty slot
    dirty_[slot] = 0;
    dirty_slots_.pop_back();
  }
}

QdMetrics qd_metrics(const ArchiveView& a, bool has_fitness, double lower_bound) {
  constexpr double nan = std::numeric_limits<double>::quiet_NaN();
  if (!has_fitness) return {nan, nan, nan};
  const std::size_t n = a.size();
  double score = 0.0, sum = 0.0, best = -std::numeric_limits<double>::infinity();
  for (std::size_t slot = 0; slot < n; ++slot) {
    const double f = a.fitness(slot);
    score += f - lower_bound;
    sum += f;
    best = std::max(best, f);
  }
  if (n == 0) return {std::isnan(lower_bound) ? nan : 0.0, nan, nan};
  return {std::isnan(lower_bound) ? nan : score, best, sum / static_cast<double>(n)};
}

}  // namespace qd::runtime
