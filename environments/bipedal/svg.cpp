// SVG drawing of one rollout: terrain and hull path (walker); ground, ball path and hull path (kicker).
#include "bipedal.hpp"

#include <algorithm>

namespace qd::bipedal {
namespace {

constexpr double kPixelsPerUnit = 12.0;
constexpr double kTopY = 9.0;  // world y drawn at the top edge
constexpr double kWidthUnits = kTerrainFull;
constexpr double kHeightUnits = 7.0;

double px(double x) {
  return x * kPixelsPerUnit;
}
double py(double y) {
  return (kTopY - y) * kPixelsPerUnit;
}

void polyline(std::ostream& out, const Series& s, int col_x, int col_y, const char* style) {
  if (s.rows() == 0) return;
  out << "<polyline fill=\"none\" " << style << " points=\"";
  for (std::size_t r = 0; r < s.rows(); ++r) out << px(s.at(r, col_x)) << ',' << py(s.at(r, col_y)) << ' ';
  out << "\"/>\n";
}

}  // namespace

bool BipedalEnvironment::draw_svg(const Trace& trace, std::ostream& out) const {
  const bool walker = options_.task == Task::kWalker;
  out << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << px(kWidthUnits) << "\" height=\""
      << kHeightUnits * kPixelsPerUnit << "\" viewBox=\"0 0 " << px(kWidthUnits) << ' ' << kHeightUnits * kPixelsPerUnit
      << "\">\n";
  out << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  out << "<polyline fill=\"none\" stroke=\"#444\" stroke-width=\"2\" points=\"";
  const auto& heights = walker_terrain_heights();
  for (int i = 0; i < kTerrainLength; ++i)
    out << px(i * kTerrainStep) << ',' << py(walker ? heights[static_cast<std::size_t>(i)] : kTerrainHeight) << ' ';
  out << "\"/>\n";
  if (walker) {
    polyline(out, trace.main, 0, 1, "stroke=\"#1f77b4\" stroke-width=\"2\"");
  } else {
    polyline(out, trace.aux, 0, 1, "stroke=\"#1f77b4\" stroke-width=\"2\"");
    polyline(out, trace.main, 0, 1, "stroke=\"#d62728\" stroke-width=\"2\"");
    if (trace.main.rows() > 0) {
      const double* last = trace.main.last();
      out << "<circle cx=\"" << px(last[0]) << "\" cy=\"" << py(last[1]) << "\" r=\"" << px(1.0 / 3.0)
          << "\" fill=\"#d62728\"/>\n";
    }
  }
  out << "</svg>\n";
  return static_cast<bool>(out);
}

}  // namespace qd::bipedal
