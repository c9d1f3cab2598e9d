#include <qd/archive.hpp>
#include <qd/errors.hpp>
#include <qd/state_io.hpp>

#include <algorithm>
#include <numeric>
#include <string>

namespace qd {

Archive::Archive(std::int64_t cells, std::size_t param_count, std::size_t descriptor_dims)
    : cells_(cells),
      param_count_(param_count),
      dims_(descriptor_dims),
      cell_slot_(static_cast<std::size_t>(cells), -1) {
  QD_CHECK(cells > 0, "archive needs at least one cell");
}

Insertion Archive::offer(std::int64_t cell, const double* params, const double* descriptor, double fitness,
                         double recn_error, bool replace) {
  QD_CHECK(cell >= 0 && cell < cells_, "cell index out of range");
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

void Archive::take_dirty(std::vector<std::size_t>& slots) {
  slots.swap(dirty_slots_);
  dirty_slots_.clear();
  for (std::size_t s : slots) dirty_[s] = 0;
}

void Archive::restore(std::size_t slot, std::int64_t cell, const double* params, const double* descriptor,
                      double fitness, double recn_error) {
  if (cell < 0 || cell >= cells_) throw StateError("archive record has an invalid cell index");
  const bool was_dirty = slot < size() && dirty_[slot];
  if (slot == size() && cell_slot_[static_cast<std::size_t>(cell)] < 0) {
    offer(cell, params, descriptor, fitness, recn_error, false);
  } else if (slot < size() && slot_cell_[slot] == cell) {
    offer(cell, params, descriptor, fitness, recn_error, true);
  } else {
    throw StateError("archive record does not fit the archive (slot " + std::to_string(slot) + ", cell " +
                     std::to_string(cell) + ")");
  }
  if (!was_dirty) {  // offer() just marked it, so it is the last dirty slot
    dirty_[slot] = 0;
    dirty_slots_.pop_back();
  }
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

double Archive::mean_recn_error() const {
  if (recn_.empty()) return 0.0;
  return std::accumulate(recn_.begin(), recn_.end(), 0.0) / static_cast<double>(recn_.size());
}

void Archive::save(std::ostream& out) const {
  state::write_tag(out, "ARCH");
  state::write<std::int64_t>(out, cells_);
  state::write<std::uint64_t>(out, param_count_);
  state::write<std::uint64_t>(out, dims_);
  state::write_vector(out, slot_cell_);
  state::write_vector(out, params_);
  state::write_vector(out, desc_);
  state::write_vector(out, fitness_);
  state::write_vector(out, recn_);
}

void Archive::load(std::istream& in) {
  state::expect_tag(in, "ARCH");
  if (state::read<std::int64_t>(in) != cells_ || state::read<std::uint64_t>(in) != param_count_ ||
      state::read<std::uint64_t>(in) != dims_)
    throw StateError("archive in checkpoint has a different shape than this experiment");
  slot_cell_ = state::read_vector<std::int64_t>(in);
  params_ = state::read_vector<double>(in);
  desc_ = state::read_vector<double>(in);
  fitness_ = state::read_vector<double>(in);
  recn_ = state::read_vector<double>(in);
  const std::size_t m = slot_cell_.size();
  if (params_.size() != m * param_count_ || desc_.size() != m * dims_ || fitness_.size() != m || recn_.size() != m)
    throw StateError("archive in checkpoint is inconsistent");
  std::fill(cell_slot_.begin(), cell_slot_.end(), -1);
  for (std::size_t s = 0; s < m; ++s) {
    const std::int64_t c = slot_cell_[s];
    if (c < 0 || c >= cells_ || cell_slot_[static_cast<std::size_t>(c)] >= 0)
      throw StateError("archive in checkpoint has an invalid cell index");
    cell_slot_[static_cast<std::size_t>(c)] = static_cast<std::int64_t>(s);
  }
  // Conservative: every loaded slot counts as written.
  dirty_.assign(m, 1);
  dirty_slots_.resize(m);
  std::iota(dirty_slots_.begin(), dirty_slots_.end(), std::size_t{0});
}

}  // namespace qd
