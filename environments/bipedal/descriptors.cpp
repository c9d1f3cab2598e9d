// walker-gait (gait_grid) and kicker-ball (simple_grid) descriptors (README.md).
#include "bipedal.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace qd::bipedal {
namespace {

constexpr double kWalkerYLow = 4.5, kWalkerYHigh = 6.2;
constexpr double kKickerYLow = 4.0, kKickerYHigh = 7.0;
constexpr double kKickerXLow = kBallStartX, kKickerXHigh = kBallStartX + 20.0;
constexpr std::int64_t kWalkerCells = 5 * 100 * 5 * 5;
constexpr std::int64_t kKickerCells = 50 * 200;

double clip(double v, double lo, double hi) {
  return std::min(std::max(v, lo), hi);
}

}  // namespace

int bin_index(double v, double lo, double hi, int n) noexcept {
  if (!std::isfinite(v)) return -1;
  return static_cast<int>(clip((v - lo) / (hi - lo) * n, 0.0, n - 1.0));
}

std::int64_t walker_gait_cell(const Trace& trace, bool corrected_contact_bins, double* values) {
  const std::size_t rows = trace.main.rows();
  if (rows == 0 || trace.aux.rows() != rows || trace.main.cols != kWalkerMainCols || trace.aux.cols != kWalkerAuxCols) {
    std::fill(values, values + 4, std::numeric_limits<double>::quiet_NaN());
    return -1;
  }
  double sum_y = 0.0, sum_left = 0.0, sum_right = 0.0;
  for (std::size_t r = 0; r < rows; ++r) {
    sum_y += trace.main.at(r, 1);
    sum_left += trace.aux.at(r, 0);
    sum_right += trace.aux.at(r, 1);
  }
  const double n = static_cast<double>(rows);
  values[0] = sum_y / n;
  values[1] = trace.main.last()[0] / kTerrainFull;
  values[2] = sum_left / n;
  values[3] = sum_right / n;

  const int d0 = bin_index(clip(values[0], kWalkerYLow, kWalkerYHigh), kWalkerYLow, kWalkerYHigh, 5);
  const int d1 = bin_index(values[1], 0.0, 1.0, 100);
  // Reference bug kept by default: 10 contact bins laid out with stride 5, so cells collide.
  const int contact_bins = corrected_contact_bins ? 5 : 10;
  const int d2 = bin_index(values[2], 0.0, 1.0, contact_bins);
  const int d3 = bin_index(values[3], 0.0, 1.0, contact_bins);
  if (d0 < 0 || d1 < 0 || d2 < 0 || d3 < 0) return -1;
  const std::int64_t cell = std::int64_t{d0} * 2500 + std::int64_t{d1} * 25 + std::int64_t{d2} * 5 + d3;
  return (cell >= 0 && cell < kWalkerCells) ? cell : -1;
}

std::int64_t kicker_ball_cell(const Trace& trace, double* values) {
  const std::size_t rows = trace.main.rows();
  if (rows == 0 || trace.main.cols != kKickerMainCols) {
    std::fill(values, values + 2, std::numeric_limits<double>::quiet_NaN());
    return -1;
  }
  double max_y = -std::numeric_limits<double>::infinity();
  for (std::size_t r = 0; r < rows; ++r) max_y = std::max(max_y, trace.main.at(r, 1));
  values[0] = max_y;
  values[1] = trace.main.last()[0];
  const int d0 = bin_index(clip(values[0], kKickerYLow, kKickerYHigh), kKickerYLow, kKickerYHigh, 50);
  const int d1 = bin_index(clip(values[1], kKickerXLow, kKickerXHigh), kKickerXLow, kKickerXHigh, 200);
  if (d0 < 0 || d1 < 0) return -1;
  return std::int64_t{d0} * 200 + d1;
}

WalkerGaitDescriptor::WalkerGaitDescriptor(const Config& cfg, const BuildContext&)
    : corrected_(cfg.get_string("contact_bins") == "corrected") {}

GridSpec WalkerGaitDescriptor::grid() const {
  GridSpec g;
  g.shape = {5, 100, 5, 5};
  g.names = {"mean_hull_y", "final_hull_x_fraction", "left_contact_fraction", "right_contact_fraction"};
  g.lower = {kWalkerYLow, 0.0, 0.0, 0.0};
  g.upper = {kWalkerYHigh, 1.0, 1.0, 1.0};
  g.cells = kWalkerCells;
  return g;
}

void WalkerGaitDescriptor::describe(const Trace* traces, std::size_t n, std::int64_t* cells, double* values) const {
  for (std::size_t i = 0; i < n; ++i) cells[i] = walker_gait_cell(traces[i], corrected_, values + 4 * i);
}

KickerBallDescriptor::KickerBallDescriptor(const Config&, const BuildContext&) {}

GridSpec KickerBallDescriptor::grid() const {
  GridSpec g;
  g.shape = {50, 200};
  g.names = {"max_ball_y", "final_ball_x"};
  g.lower = {kKickerYLow, kKickerXLow};
  g.upper = {kKickerYHigh, kKickerXHigh};
  g.cells = kKickerCells;
  return g;
}

void KickerBallDescriptor::describe(const Trace* traces, std::size_t n, std::int64_t* cells, double* values) const {
  for (std::size_t i = 0; i < n; ++i) cells[i] = kicker_ball_cell(traces[i], values + 2 * i);
}

}  // namespace qd::bipedal
