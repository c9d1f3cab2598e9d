#include "striker_env.hpp"

#include <qd/errors.hpp>

#include <cmath>
#include <sstream>

namespace qd::striker {
namespace {

Options options_from(const Config& config) {
  Options options;
  options.mix_scale = config.get_bool("mix_scale");
  // The core has already rejected any value outside the declared choices.
  options.mix_scale_elements =
      config.get_string("mix_scale_elements") == "paper" ? MixScaleElements::kPaper : MixScaleElements::kCompanion;
  options.puck_hits_target = config.get_bool("puck_hits_target");
  options.max_steps = static_cast<int>(config.get_int("max_steps"));
  return options;
}

// Polyline points in world units from normalised (x_n, y_n) trajectory rows; non-finite rows are skipped.
std::string polyline_points(const Series& rows) {
  std::ostringstream points;
  for (std::size_t r = 0; r < rows.rows(); ++r) {
    const double x = world_x(rows.at(r, 0)), y = world_y(rows.at(r, 1));
    if (!std::isfinite(x) || !std::isfinite(y)) continue;
    points << x << ',' << y << ' ';
  }
  return points.str();
}

}  // namespace

StrikerEnvironment::StrikerEnvironment(const Config& config, const BuildContext&)
    : StrikerEnvironment(options_from(config)) {}

StrikerEnvironment::StrikerEnvironment(const Options& options) : options_(options) {
  if (options_.max_steps < kRowEvery) throw ConfigError("max_steps", "must be at least 20 (one trajectory row)");
  // Constructed on the main thread, before any parallel rollout.
  warm_up_box2d();
}

EnvironmentInfo StrikerEnvironment::info() const {
  EnvironmentInfo info;
  info.observation_size = kObservationSize;
  info.action_size = kActionSize;
  info.max_steps = options_.max_steps;
  return info;
}

void StrikerEnvironment::rollout(const RolloutBatch& batch, Trace* traces) const {
  QD_CHECK(batch.shape && batch.params, "striker: rollout batch without policy shape or parameters");
  Policy policy(*batch.shape);  // one per call: Policy is not thread-safe
  for (std::size_t i = batch.begin; i < batch.end; ++i) run_policy_episode(options_, policy, batch.row(i), traces[i]);
}

bool StrikerEnvironment::draw_svg(const Trace& trace, std::ostream& out) const {
  std::ostringstream svg;
  svg << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"500\" height=\"500\" viewBox=\"0 0 100 100\">\n"
      << "<title>striker: puck path (blue), striker path (red), status " << to_string(trace.status) << ", "
      << trace.steps << " steps</title>\n"
      << "<rect x=\"0\" y=\"0\" width=\"100\" height=\"100\" fill=\"#f7f7f2\"/>\n"
      // World y points up; SVG y points down.
      << "<g transform=\"matrix(1 0 0 -1 0 100)\">\n"
      << "<g fill=\"#222\">\n"
      << "<rect x=\"0\" y=\"0\" width=\"100\" height=\"1\"/>\n"   // S
      << "<rect x=\"99\" y=\"0\" width=\"1\" height=\"100\"/>\n"  // E
      << "<rect x=\"0\" y=\"99\" width=\"100\" height=\"1\"/>\n"  // N
      << "<rect x=\"0\" y=\"0\" width=\"1\" height=\"100\"/>\n"   // W
      << "</g>\n"
      << "<circle cx=\"" << kTargetX << "\" cy=\"" << kTargetY << "\" r=\"" << kTargetRadius
      << "\" fill=\"#66e666\" fill-opacity=\"0.6\" stroke=\"#3a3\" stroke-width=\"0.4\"/>\n"
      << "<rect x=\"" << kStrikerStartX - kStrikerHalfWidth << "\" y=\"" << kStrikerStartY - kStrikerHalfHeight
      << "\" width=\"" << 2 * kStrikerHalfWidth << "\" height=\"" << 2 * kStrikerHalfHeight
      << "\" fill=\"none\" stroke=\"#e66666\" stroke-width=\"0.4\" stroke-dasharray=\"1 1\"/>\n"
      << "<circle cx=\"" << kPuckStartX << "\" cy=\"" << kPuckStartY << "\" r=\"" << kPuckRadius
      << "\" fill=\"none\" stroke=\"#6666e6\" stroke-width=\"0.4\" stroke-dasharray=\"1 1\"/>\n";
  if (trace.aux.cols == 3 && trace.aux.rows() > 0) {
    svg << "<polyline fill=\"none\" stroke=\"#d33\" stroke-width=\"0.5\" points=\"" << polyline_points(trace.aux)
        << "\"/>\n";
    const double* last = trace.aux.last();
    const double x = world_x(last[0]), y = world_y(last[1]);
    if (std::isfinite(x) && std::isfinite(y) && std::isfinite(last[2]))
      svg << "<rect x=\"" << -kStrikerHalfWidth << "\" y=\"" << -kStrikerHalfHeight << "\" width=\""
          << 2 * kStrikerHalfWidth << "\" height=\"" << 2 * kStrikerHalfHeight << "\" transform=\"translate(" << x
          << ' ' << y << ") rotate(" << last[2] * (180.0 / 3.14159265358979323846)
          << ")\" fill=\"#e66666\" fill-opacity=\"0.7\" stroke=\"#a22\" stroke-width=\"0.3\"/>\n";
  }
  if (trace.main.cols == 2 && trace.main.rows() > 0) {
    svg << "<polyline fill=\"none\" stroke=\"#33d\" stroke-width=\"0.5\" points=\"" << polyline_points(trace.main)
        << "\"/>\n";
    const double x = world_x(trace.main.last()[0]), y = world_y(trace.main.last()[1]);
    if (std::isfinite(x) && std::isfinite(y))
      svg << "<circle cx=\"" << x << "\" cy=\"" << y << "\" r=\"" << kPuckRadius
          << "\" fill=\"#6666e6\" stroke=\"#22a\" stroke-width=\"0.3\"/>\n";
  }
  svg << "</g>\n</svg>\n";
  out << svg.str();
  return static_cast<bool>(out);
}

}  // namespace qd::striker
