// Descriptor: maps traces to behaviour cells.
//
// Contract
//  * grid() is fixed for the lifetime of the object.
//  * describe() is const and thread-safe. For trace i it writes cells[i] in [0, grid().cells) and
//    values[i * dims .. (i + 1) * dims) with dims = grid().dims() (the continuous descriptor,
//    written to archive snapshots). A trace that cannot be described gets cells[i] = -1 and is not
//    inserted; traces with status != kOk are never passed in. `values` arrives zeroed.
//  * A descriptor adapter (registered with qd::descriptor_adapter, such as "cvt") gets the
//    descriptor it wraps in BuildContext::wrapped and may call its grid() and describe().
//  * A descriptor that computes its grid (CVT centroids) finds the grid of the run being resumed in
//    BuildContext::stored_grid and should reuse it, so a resumed run keeps its cells exactly.
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
