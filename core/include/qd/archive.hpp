// ArchiveView: what plugins see of the grid archive (the paper's A: at most one elite per
// behaviour cell). Read-only; the core's archive implements it.
//
// Elites are numbered by "slot" 0 .. size() - 1 in the order their cells were first filled; a
// replacement keeps the slot. Pointers returned here stay valid until the archive next changes,
// which never happens during a mutator or representation call.
#pragma once

#include <qd/export.hpp>

#include <cstddef>
#include <cstdint>

namespace qd {

class QD_EXPORT ArchiveView {
 public:
  virtual ~ArchiveView();

  virtual std::int64_t cells() const noexcept = 0;  // grid size
  virtual std::size_t size() const noexcept = 0;    // elites
  virtual std::size_t param_count() const noexcept = 0;
  virtual std::size_t descriptor_dims() const noexcept = 0;

  // The slot of the elite in `cell`; -1 when the cell is empty or outside the grid.
  virtual std::int64_t slot_of(std::int64_t cell) const noexcept = 0;
  bool occupied(std::int64_t cell) const noexcept { return slot_of(cell) >= 0; }

  // Per elite, slot < size().
  virtual std::int64_t cell(std::size_t slot) const = 0;
  virtual const double* params(std::size_t slot) const = 0;      // param_count() values
  virtual const double* descriptor(std::size_t slot) const = 0;  // descriptor_dims() values
  virtual double fitness(std::size_t slot) const = 0;
  // ‖θ − Dec(Enc(θ))‖ stored when the elite entered the archive (0 without a latent model).
  virtual double recn_error(std::size_t slot) const = 0;

  // Filled cells / all cells.
  double coverage() const noexcept;
  // Mean stored reconstruction error over the elites, in slot order (PoMS threshold); 0 when empty.
  double mean_recn_error() const;
};

}  // namespace qd
