// The Striker "contact_grid" behaviour descriptor (README.md, "Descriptor"): which walls the puck
// touched first (17 classes) x final puck position (30 x 30 bins) = 15300 cells.
//
// Cell index = g * 900 + py * 30 + px, i.e. x varies fastest, as in the reference: row-major over
// the GridSpec's (walls, y, x). The continuous values are written in the order (g, x_n, y_n).
#pragma once

#include <qd/config.hpp>
#include <qd/descriptor.hpp>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace qd::striker {

inline constexpr int kWallClasses = 17;
inline constexpr int kPositionBins = 30;
inline constexpr std::int64_t kCells = static_cast<std::int64_t>(kWallClasses) * kPositionBins * kPositionBins;

// Ranges computed the way the reference computes them (offset = DH/H + DD/W), so the bin edges
// are bit-identical to its float64 arithmetic.
inline constexpr double kRangeOffset = 1.0 / 100.0 + 2.5 / 100.0;
inline constexpr double kMinX = -1.0 + kRangeOffset;
inline constexpr double kMaxX = 1.0 - kRangeOffset;
inline constexpr double kMinY = -0.5 + kRangeOffset;
inline constexpr double kMaxY = 1.5 - kRangeOffset;

// Class of a wall-contact event list (wall indices 0 S, 1 E, 2 N, 3 W, in contact order):
// 0 no wall; 1 + w one distinct wall; 5 + 3 * w0 + rank(w1 among the other three walls) for the
// first two distinct walls in order of first touch. Later walls are ignored. Returns -1 if an
// event is not a wall index.
int wall_class(const int* events, std::size_t count);

// The name of each wall class, for grid.toml's labels: "none", "S", "E", "N", "W", then "S-E" (the
// puck touched S first, then E), "S-N", ... in the order of the class index.
std::vector<std::string> wall_class_labels();

// int(clip((v - lo) / (hi - lo) * 30, 0, 29)) with the reference's ranges; -1 for non-finite v.
int bin_x(double x_n);
int bin_y(double y_n);

inline std::int64_t cell_index(int wall_class_index, int px, int py) {
  return static_cast<std::int64_t>(wall_class_index) * kPositionBins * kPositionBins +
         static_cast<std::int64_t>(py) * kPositionBins + px;
}

class ContactGridDescriptor final : public Descriptor {
 public:
  ContactGridDescriptor() = default;
  ContactGridDescriptor(const Config&, const BuildContext&) {}

  GridSpec grid() const override;
  // Reads events (wall history) and the last main row (final puck x_n, y_n). Writes values
  // (g, x_n, y_n). A trace without rows, with a non-wall event or a non-finite position gets -1.
  void describe(const Trace* traces, std::size_t n, std::int64_t* cells, double* values) const override;
};

}  // namespace qd::striker
