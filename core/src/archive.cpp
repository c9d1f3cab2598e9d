#include <qd/archive.hpp>
#include <qd/errors.hpp>
#include <qd/state_io.hpp>

#include <algorithm>
#include <cstring>
#include <numeric>
#include <string>
#include <thread>

#if defined(__SSE2__)
#include <immintrin.h>
#endif

namespace qd {
namespace {

void pause() {
#if defined(__SSE2__)
  _mm_pause();
#endif
  std::this_thread::yield();
}

}  // namespace

Archive::Archive(std::int64_t cells, std::size_t param_count, std::size_t descriptor_dims)
    : cells_(cells),
      param_count_(param_count),
      dims_(descriptor_dims),
      cell_slot_(static_cast<std::size_t>(cells), -1) {
  QD_CHECK(cells > 0, "archive needs at least one cell");
  reserve_slots();
}

void Archive::reserve_slots() {
  // At most one slot per cell: the per-slot arrays never move, so a capture can read them while
  // the loop adds slots. Only params_ (the big one) grows on demand.
  const auto n = static_cast<std::size_t>(cells_);
  slot_cell_.reserve(n);
  desc_.reserve(n * dims_);
  fitness_.reserve(n);
  recn_.reserve(n);
  dirty_.reserve(n);
  // Deferred copies need parameter storage that never moves: reserve it for every cell when that
  // is at most 2 GiB of address space (pages are only backed once written).
  constexpr std::size_t kMaxReservedBytes = std::size_t{2} << 30;
  if (param_count_ > 0 && n <= kMaxReservedBytes / sizeof(double) / param_count_) {
    params_.reserve(n * param_count_);
    source_.resize(n, nullptr);
  }
}

std::int64_t Archive::place(std::int64_t cell, const double* descriptor, double fitness, double recn_error,
                            bool replace, Insertion& result) {
  QD_CHECK(cell >= 0 && cell < cells_, "cell index out of range");
  std::int64_t slot = cell_slot_[static_cast<std::size_t>(cell)];
  result = Insertion::kReplaced;
  if (slot < 0) {
    if (params_.size() + param_count_ > params_.capacity() && capture_ &&
        capture_->left.load(std::memory_order_acquire) != 0) {
      // Growing moves the parameters a capture reads from: copy what is left here first.
      for (std::size_t s : *capture_->slots) claim_and_copy(s);
      wait_for_capture();
    }
    QD_CHECK(params_.size() + param_count_ <= params_.capacity() || pending_copies() == 0,
             "archive storage would move under a deferred copy");
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
    result = Insertion::kRejected;
    return -1;
  } else {
    before_write(static_cast<std::size_t>(slot));
  }
  const auto s = static_cast<std::size_t>(slot);
  std::copy(descriptor, descriptor + dims_, desc_.begin() + static_cast<std::ptrdiff_t>(s * dims_));
  fitness_[s] = fitness;
  recn_[s] = recn_error;
  mark_dirty(s);
  return slot;
}

void Archive::prefetch(const std::int64_t* cells, std::size_t n) const {
  // Two passes: the cells' slots first, then (slots known) the slots' fields, all in flight at once.
  for (std::size_t i = 0; i < n; ++i)
    if (cells[i] >= 0 && cells[i] < cells_) __builtin_prefetch(&cell_slot_[static_cast<std::size_t>(cells[i])]);
  for (std::size_t i = 0; i < n; ++i) {
    if (cells[i] < 0 || cells[i] >= cells_) continue;
    const std::int64_t slot = cell_slot_[static_cast<std::size_t>(cells[i])];
    if (slot < 0) continue;
    const auto s = static_cast<std::size_t>(slot);
    __builtin_prefetch(&fitness_[s], 1);
    __builtin_prefetch(&recn_[s], 1);
    __builtin_prefetch(&dirty_[s], 1);
    if (dims_ > 0) __builtin_prefetch(&desc_[s * dims_], 1);
    if (!source_.empty()) __builtin_prefetch(&source_[s], 1);
  }
}

Insertion Archive::offer(std::int64_t cell, const double* params, const double* descriptor, double fitness,
                         double recn_error, bool replace) {
  QD_CHECK(pending_copies() == 0, "Archive::offer while deferred copies are pending");
  Insertion result;
  const std::int64_t slot = place(cell, descriptor, fitness, recn_error, replace, result);
  if (slot >= 0)
    std::memcpy(params_.data() + static_cast<std::size_t>(slot) * param_count_, params, param_count_ * sizeof(double));
  return result;
}

Insertion Archive::offer_deferred(std::int64_t cell, const double* params, const double* descriptor, double fitness,
                                  double recn_error, bool replace, std::vector<DeferredCopy>& copies) {
  QD_CHECK(can_defer_copies(), "offer_deferred on an archive that cannot defer copies");
  Insertion result;
  const std::int64_t slot = place(cell, descriptor, fitness, recn_error, replace, result);
  if (slot >= 0) {
    const auto s = static_cast<std::size_t>(slot);
    source_[s] = params;
    ++pending_;
    copies.push_back({s, params});
  }
  return result;
}

void Archive::complete_copies(const std::vector<DeferredCopy>& copies) {
  // Only the parameter rows: the loop's thread keeps every other field, and a row copied twice
  // (two offers to one slot) ends as the later one because batches complete in order.
  for (const DeferredCopy& copy : copies)
    std::memcpy(params_.data() + copy.slot * param_count_, copy.source, param_count_ * sizeof(double));
}

void Archive::release_copies(const std::vector<DeferredCopy>& copies) {
  QD_CHECK(pending_ >= copies.size(), "release of copies that were not offered");
  for (const DeferredCopy& copy : copies)
    if (source_[copy.slot] == copy.source) source_[copy.slot] = nullptr;  // else a later offer refers
  pending_ -= copies.size();
}

void Archive::write_record(std::size_t slot, char* out) const {
  const auto slot64 = static_cast<std::int64_t>(slot);
  std::memcpy(out, &slot64, 8);
  std::memcpy(out + 8, &slot_cell_[slot], 8);
  std::memcpy(out + 16, &fitness_[slot], 8);
  std::memcpy(out + 24, &recn_[slot], 8);
  std::memcpy(out + 32, descriptor(slot), dims_ * sizeof(double));
  // Not params(): the capture thread must not read pending_, which the loop updates meanwhile.
  // source_[slot] itself is stable here: the loop copies a listed slot before it offers to it.
  const double* row = !source_.empty() && source_[slot] ? source_[slot] : params_.data() + slot * param_count_;
  std::memcpy(out + 32 + dims_ * sizeof(double), row, param_count_ * sizeof(double));
}

void Archive::begin_capture(const std::vector<std::size_t>& slots, char* out) {
  QD_CHECK(pending_copies() == 0, "begin_capture while deferred copies are pending");
  if (!capture_) capture_ = std::make_unique<Capture>(static_cast<std::size_t>(cells_));
  Capture& c = *capture_;
  QD_CHECK(c.left.load(std::memory_order_acquire) == 0, "begin_capture while a capture is in progress");
  for (std::size_t k = 0; k < slots.size(); ++k) {
    const std::size_t s = slots[k];
    QD_CHECK(s < size(), "capture of a slot the archive does not have");
    QD_CHECK(c.state[s].load(std::memory_order_relaxed) == 0, "slot listed twice in a capture");
    c.index[s] = k;
    c.state[s].store(1, std::memory_order_relaxed);
  }
  c.slots = &slots;
  c.out = out;
  c.left.store(slots.size(), std::memory_order_release);
}

bool Archive::claim_and_copy(std::size_t slot) {
  Capture& c = *capture_;
  std::uint8_t expected = 1;
  if (!c.state[slot].compare_exchange_strong(expected, 2, std::memory_order_acq_rel)) return false;
  write_record(slot, c.out + c.index[slot] * record_bytes());
  c.state[slot].store(0, std::memory_order_release);
  c.left.fetch_sub(1, std::memory_order_acq_rel);
  return true;
}

void Archive::wait_for_capture() const {
  while (capture_->left.load(std::memory_order_acquire) != 0) pause();
}

void Archive::capture_before_write(std::size_t slot) {
  if (capture_->state[slot].load(std::memory_order_acquire) == 0) return;
  if (!claim_and_copy(slot))  // the other thread is copying it right now
    while (capture_->state[slot].load(std::memory_order_acquire) != 0) pause();
}

void Archive::capture() {
  if (!capture_ || capture_->left.load(std::memory_order_acquire) == 0) return;
  for (std::size_t s : *capture_->slots) claim_and_copy(s);
  wait_for_capture();
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
  QD_CHECK(pending_copies() == 0, "archive save while deferred copies are pending");
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
  QD_CHECK(!capture_ || capture_->left.load() == 0, "archive load during a capture");
  QD_CHECK(pending_copies() == 0, "archive load while deferred copies are pending");
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
  reserve_slots();
  // Conservative: every loaded slot counts as written.
  dirty_.assign(m, 1);
  dirty_slots_.resize(m);
  std::iota(dirty_slots_.begin(), dirty_slots_.end(), std::size_t{0});
}

}  // namespace qd
