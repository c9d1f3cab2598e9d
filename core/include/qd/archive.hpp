// The grid archive: at most one elite per behaviour cell (spec 3.3).
//
// Elites are stored densely in insertion order ("slots"); a cell -> slot index maps cells to them.
// Slots are never removed, only overwritten on replacement, so slot order is deterministic.
// Threading: const members may run concurrently; offer() must not overlap anything, except
// capture() (below), which a background thread may run while the loop offers.
#pragma once

#include <qd/export.hpp>
#include <qd/rng.hpp>
#include <qd/types.hpp>

#include <Eigen/Core>

#include <atomic>
#include <cstdint>
#include <iosfwd>
#include <memory>
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
  const double* params(std::size_t slot) const {
    if (pending_ != 0)  // a row whose deferred copy is not released yet is read where it is
      if (const double* p = source_[slot]) return p;
    return params_.data() + slot * param_count_;
  }
  const double* descriptor(std::size_t slot) const { return desc_.data() + slot * dims_; }
  double fitness(std::size_t slot) const { return fitness_[slot]; }
  double recn_error(std::size_t slot) const { return recn_[slot]; }
  void set_recn_error(std::size_t slot, double e) {
    before_write(slot);
    recn_[slot] = e;
    mark_dirty(slot);
  }

  // Puts an individual into `cell`: adds it when the cell is empty; when occupied, replaces the
  // occupant if `replace` is true (the insertion rule's decision) and rejects it otherwise.
  Insertion offer(std::int64_t cell, const double* params, const double* descriptor, double fitness, double recn_error,
                  bool replace);

  // Deferred copies, so the loop need not wait for memory: offer_deferred() decides exactly as
  // offer() but does not copy the parameters. The slot refers to `params` (the caller's row) and
  // the copy is appended to `copies`. One other thread carries the batches out in order with
  // complete_copies() (it writes nothing but the parameter rows), and afterwards the loop's thread
  // calls release_copies() with the same batch, from which on the slots read the archive's own
  // rows. params(slot) reads the referred row until then, so nothing depends on when copies
  // happen. The caller keeps each referred row valid and unchanged until it is released, and
  // releases every copy before offer(), restore(), save(), load() or begin_capture(). Only when
  // can_defer_copies(): storage for every cell is reserved then, so parameters never move.
  struct DeferredCopy {
    std::size_t slot;
    const double* source;
  };
  bool can_defer_copies() const noexcept { return !source_.empty(); }
  Insertion offer_deferred(std::int64_t cell, const double* params, const double* descriptor, double fitness,
                           double recn_error, bool replace, std::vector<DeferredCopy>& copies);
  void complete_copies(const std::vector<DeferredCopy>& copies);
  void release_copies(const std::vector<DeferredCopy>& copies);
  std::size_t pending_copies() const noexcept { return pending_; }

  // A cache hint, no change: the caller is about to offer to these cells (negative ones are
  // skipped). The rollouts between two batches' insertions evict the archive's per-slot arrays, so
  // without it each offer waits for several cache misses in turn.
  void prefetch(const std::int64_t* cells, std::size_t n) const;

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

  // A slot's record in checkpoint files: slot, cell (int64), fitness, recn error, descriptor,
  // parameters (doubles), native byte order.
  std::size_t record_bytes() const noexcept { return 4 * sizeof(std::int64_t) + (dims_ + param_count_) * 8; }
  void write_record(std::size_t slot, char* out) const;

  // Background capture, so a checkpoint need not copy the archive on the loop's thread.
  // begin_capture() lists slots and a buffer: slot slots[k]'s record goes to out + k * record_bytes().
  // capture() (any one other thread) copies the listed records not yet copied and returns when
  // all are in the buffer. Meanwhile the loop may go on: offer() and set_recn_error() on a listed
  // slot not yet copied copy it first, so the buffer always holds the archive as it was at
  // begin_capture(). `slots` and `out` must stay valid until capture() returns; a new
  // begin_capture() must wait for that.
  void begin_capture(const std::vector<std::size_t>& slots, char* out);
  void capture();

 private:
  void mark_dirty(std::size_t slot) {
    if (!dirty_[slot]) {
      dirty_[slot] = 1;
      dirty_slots_.push_back(slot);
    }
  }
  void reserve_slots();
  // The shared part of offer() and offer_deferred(): the slot that takes the individual (-1 when
  // rejected), with everything but the parameters stored.
  std::int64_t place(std::int64_t cell, const double* descriptor, double fitness, double recn_error, bool replace,
                     Insertion& result);
  // Called before any change to an existing slot (and before storage can move).
  void before_write(std::size_t slot) {
    if (capture_ && capture_->left.load(std::memory_order_acquire) != 0) capture_before_write(slot);
  }
  void capture_before_write(std::size_t slot);
  bool claim_and_copy(std::size_t slot);
  void wait_for_capture() const;

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

  struct Capture {
    explicit Capture(std::size_t cells) : state(new std::atomic<std::uint8_t>[cells]), index(new std::size_t[cells]) {
      for (std::size_t s = 0; s < cells; ++s) state[s].store(0, std::memory_order_relaxed);
    }
    // Per slot: 0 nothing to do, 1 listed and not yet copied, 2 being copied.
    std::unique_ptr<std::atomic<std::uint8_t>[]> state;
    std::unique_ptr<std::size_t[]> index;  // per slot: its position in the list
    const std::vector<std::size_t>* slots = nullptr;
    char* out = nullptr;
    std::atomic<std::size_t> left{0};  // listed records not yet in the buffer
  };
  std::unique_ptr<Capture> capture_;  // made by the first begin_capture()

  // Deferred copies; written by the loop's thread only.
  std::vector<const double*> source_;  // per slot: the row to read until released (empty: cannot defer)
  std::size_t pending_ = 0;            // offered, not yet released
};

}  // namespace qd
