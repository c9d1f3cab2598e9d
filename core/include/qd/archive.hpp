// The grid archive: at most one elite per behaviour cell (spec 3.3).
//
// Elites are stored densely in insertion order ("slots"); a cell -> slot index maps cells to them.
// Slots are never removed, only overwritten on replacement, so slot order is deterministic.
// Threading: const members may run concurrently; offer() must not overlap anything.
#pragma once

#include <qd/export.hpp>
#include <qd/rng.hpp>
#include <qd/types.hpp>

#include <Eigen/Core>

#include <cstdint>
#include <iosfwd>
#include <vector>

namespace qd {

// Selected parents: copies of the elites' rows.
struct Parents {
  Matrix theta;       // n × P
  Vector recn_error;  // stored reconstruction errors (0 without a model)
  std::vector<std::int64_t> cells;
};

enum class Insertion : std::uint8_t { kAdded = 0, kReplaced = 1, kRejected = 2, kInvalid = 3 };

class QD_EXPORT Archive {
 public:
  Archive(std::int64_t cells, std::size_t param_count, std::size_t descriptor_dims);

  std::int64_t cells() const noexcept { return cells_; }
  std::size_t size() const noexcept { return slot_cell_.size(); }
  double coverage() const noexcept { return static_cast<double>(size()) / static_cast<double>(cells_); }
  std::size_t param_count() const noexcept { return param_count_; }
  std::size_t descriptor_dims() const noexcept { return dims_; }

  // -1 when empty.
  std::int64_t slot_of(std::int64_t cell) const { return cell_slot_[static_cast<std::size_t>(cell)]; }
  bool occupied(std::int64_t cell) const { return slot_of(cell) >= 0; }

  // Slot accessors, slot < size().
  std::int64_t cell(std::size_t slot) const { return slot_cell_[slot]; }
  const double* params(std::size_t slot) const { return params_.data() + slot * param_count_; }
  const double* descriptor(std::size_t slot) const { return desc_.data() + slot * dims_; }
  double fitness(std::size_t slot) const { return fitness_[slot]; }
  double recn_error(std::size_t slot) const { return recn_[slot]; }
  void set_recn_error(std::size_t slot, double e) {
    recn_[slot] = e;
    mark_dirty(slot);
  }

  // Puts an individual into `cell`: adds it when the cell is empty; when occupied, replaces the
  // occupant if `replace` is true (the insertion rule's decision) and rejects it otherwise.
  Insertion offer(std::int64_t cell, const double* params, const double* descriptor, double fitness, double recn_error,
                  bool replace);

  // Draws n parents uniformly over occupied cells: without replacement when size() >= n, with
  // replacement otherwise (spec 3.3.3.1). Requires size() > 0.
  void select(std::size_t n, Rng& rng, Parents& out) const;

  // Mean stored reconstruction error (PoMS threshold); 0 when empty.
  double mean_recn_error() const;

  void save(std::ostream& out) const;
  void load(std::istream& in);

  // Incremental checkpoints. take_dirty() moves out the slots written (added, replaced or given a
  // new error) since the previous call, in first-write order, and clears the marks. restore() puts
  // a saved slot back: slot == size() appends it, a smaller slot overwrites (same cell).
  void take_dirty(std::vector<std::size_t>& slots);
  void restore(std::size_t slot, std::int64_t cell, const double* params, const double* descriptor, double fitness,
               double recn_error);

 private:
  void mark_dirty(std::size_t slot) {
    if (!dirty_[slot]) {
      dirty_[slot] = 1;
      dirty_slots_.push_back(slot);
    }
  }

  std::int64_t cells_;
  std::size_t param_count_;
  std::size_t dims_;
  std::vector<std::int64_t> cell_slot_;
  std::vector<std::int64_t> slot_cell_;
  std::vector<double> params_;
  std::vector<double> desc_;
  std::vector<double> fitness_;
  std::vector<double> recn_;
  std::vector<std::uint8_t> dirty_;  // per slot
  std::vector<std::size_t> dirty_slots_;
};

}  // namespace qd
