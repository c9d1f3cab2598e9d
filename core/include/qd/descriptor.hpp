// Descriptor: maps traces to behaviour cells.
//
// Contract
//  * grid() is fixed for the lifetime of the object.
//  * describe() is const and thread-safe. For trace i it writes cells[i] in [0, grid().cells) and
//    values[i * dims .. (i + 1) * dims) with dims = grid().shape.size() (the continuous descriptor,
//    written to archive snapshots). A trace that cannot be described gets cells[i] = -1 and is not
//    inserted; traces with status != kOk are never passed in. `values` arrives zeroed.
//  * Every offspring described into a cell is offered to that cell; which one stays is decided by
//    [experiment] insertion (a coin flip, or the higher Trace::fitness), not by the descriptor.
#pragma once

#include <qd/component.hpp>
#include <qd/export.hpp>
#include <qd/types.hpp>

#include <cstdint>

namespace qd {

class QD_EXPORT Descriptor : public Component {
 public:
  ~Descriptor() override;

  virtual GridSpec grid() const = 0;

  virtual void describe(const Trace* traces, std::size_t n, std::int64_t* cells, double* values) const = 0;
};

}  // namespace qd
