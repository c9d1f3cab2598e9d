// The grid archive A (paper, Sec. 3): at most one elite per behaviour cell.
//
// Elites are stored densely by slot (the order their cells were first filled); a cell -> slot
// index finds them. Slots are never removed, only overwritten on replacement, so slot order is
// deterministic. The insertion rule (coin flip or fitness) is the loop's decision, passed to
// offer(); the archive only stores.
#pragma once

#include <qd/archive.hpp>
#include <qd/mutator.hpp>
#include <qd/rng.hpp>

#include <cstdint>
#include <vector>

namespace qd::runtime {

// What the archive did with one offspring (the loop refines it into a qd::Outcome).
enum class Insertion : std::uint8_t { kAdded = 0, kReplaced = 1, kRejected = 2 };

class Archive final : public ArchiveView {
 public:
  Archive(std::int64_t cells, std::size_t param_count, std::size_t descriptor_dims);

  std::int64_t cells() const noexcept override { return cells_; }
  std::size_t size() const noexcept override { return slot_cell_.size(); }
  std::size_t param_count() const noexcept override { return param_count_; }
  std::size_t descriptor_dims() const noexcept override { return dims_; }
  std::int64_t slot_of(std::int64_t cell) const noexcept override {
    return cell < 0 || cell >= cells_ ? -1 : cell_slot_[static_cast<std::size_t>(cell)];
  }
  std::int64_t cell(std::size_t slot) const override { return slot_cell_[slot]; }
  const double* params(std::size_t slot) const override { return params_.data() + slot * param_count_; }
  const double* descriptor(std::size_t slot) const override { return desc_.data() + slot * dims_; }
  double fitness(std::size_t slot) const override { return fitness_[slot]; }
  double recn_error(std::size_t slot) const override { return recn_[slot]; }

  // Puts an individual into `cell` (0 <= cell < cells()): adds it when the cell is empty; when it
  // is occupied, replaces the occupant if `replace` is true and rejects the individual otherwise.
  Insertion offer(std::int64_t cell, const double* params, const double* descriptor, double fitness, double recn_error,
                  bool replace);
  void set_recn_error(std::size_t slot, double error);

  // Draws n parents uniformly over the elites: without replacement when size() >= n, with
  // replacement otherwise (paper, Sec. 3). Requires size() > 0.
  void select(std::size_t n, Rng& rng, Parents& out) const;

  // For incremental checkpoints: moves out the slots written (added, replaced or given a new
  // error) since the previous call, in first-write order, and clears the marks.
  void take_dirty(std::vector<std::size_t>& slots);
  // Puts a saved slot back: slot == size() appends it, a smaller slot overwrites the same cell.
  // Throws StateError when the slot does not fit.
  void restore(std::size_t slot, std::int64_t cell, const double* params, const double* descriptor, double fitness,
               double recn_error);

 private:
  void mark_dirty(std::size_t slot);

  std::int64_t cells_;
  std::size_t param_count_;
  std::size_t dims_;
  std::vector<std::int64_t> cell_slot_;  // per cell, -1 = empty
  std::vector<std::int64_t> slot_cell_;  // per slot
  std::vector<double> params_, desc_, fitness_, recn_;
  std::vector<std::uint8_t> dirty_;  // per slot
  std::vector<std::size_t> dirty_slots_;
};

// The QD metrics of an archive, each NaN where it does not apply: without a task fitness all three;
// qd_score also without a lower bound. qd_score = sum over the elites of (fitness - lower_bound), in
// slot order; max and mean over the elites (NaN for an empty archive).
struct QdMetrics {
  double qd_score, max_fitness, mean_fitness;
};
QdMetrics qd_metrics(const ArchiveView& archive, bool has_fitness, double lower_bound);

}  // namespace qd::runtime
