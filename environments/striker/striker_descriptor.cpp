#include "striker_descriptor.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace qd::striker {
namespace {

constexpr int kWalls = 4;

int bin(double v, double lo, double hi) {
  if (!std::isfinite(v)) return -1;
  // Same operation order as the reference: normalise, then scale by the bin count, then clip.
  const double scaled = (v - lo) / (hi - lo) * kPositionBins;
  return static_cast<int>(std::clamp(scaled, 0.0, static_cast<double>(kPositionBins - 1)));
}

}  // namespace

int wall_class(const int* events, std::size_t count) {
  int first = -1, second = -1;
  for (std::size_t i = 0; i < count; ++i) {
    const int w = events[i];
    if (w < 0 || w >= kWalls) return -1;
    if (first < 0)
      first = w;
    else if (second < 0 && w != first)
      second = w;
  }
  if (first < 0) return 0;
  if (second < 0) return 1 + first;
  const int rank = second - (second > first ? 1 : 0);
  return 1 + kWalls + first * (kWalls - 1) + rank;
}

std::vector<std::string> wall_class_labels() {
  static const char* const kWallNames[kWalls] = {"S", "E", "N", "W"};
  std::vector<std::string> labels(kWallClasses);
  labels[0] = "none";
  for (int w = 0; w < kWalls; ++w) labels[1 + w] = kWallNames[w];
  for (int first = 0; first < kWalls; ++first)
    for (int second = 0; second < kWalls; ++second)
      if (second != first) {
        const int events[2] = {first, second};
        labels[wall_class(events, 2)] = std::string(kWallNames[first]) + "-" + kWallNames[second];
      }
  return labels;
}

int bin_x(double x_n) {
  return bin(x_n, kMinX, kMaxX);
}
int bin_y(double y_n) {
  return bin(y_n, kMinY, kMaxY);
}

GridSpec ContactGridDescriptor::grid() const {
  GridSpec spec;
  spec.shape = {kWallClasses, kPositionBins, kPositionBins};
  // In the order of the cell index, g * 900 + py * 30 + px (row-major, x fastest), so that grid.toml
  // decomposes a cell correctly; the values written by describe() stay (g, x_n, y_n).
  spec.names = {"walls", "y", "x"};
  spec.lower = {0.0, kMinY, kMinX};
  spec.upper = {static_cast<double>(kWallClasses), kMaxY, kMaxX};
  spec.cells = kCells;
  spec.labels = {wall_class_labels(), {}, {}};
  return spec;
}

void ContactGridDescriptor::describe(const Trace* traces, std::size_t n, std::int64_t* cells, double* values) const {
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  for (std::size_t i = 0; i < n; ++i) {
    const Trace& trace = traces[i];
    double* out = values + 3 * i;
    cells[i] = -1;
    out[0] = out[1] = out[2] = kNaN;
    if (trace.main.cols != 2 || trace.main.rows() == 0) continue;
    const int g = wall_class(trace.events.data(), trace.events.size());
    const double x = trace.main.last()[0];
    const double y = trace.main.last()[1];
    out[0] = g;
    out[1] = x;
    out[2] = y;
    const int px = bin_x(x), py = bin_y(y);
    if (g < 0 || px < 0 || py < 0) continue;
    cells[i] = cell_index(g, px, py);
  }
}

}  // namespace qd::striker
