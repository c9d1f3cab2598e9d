#include "progress.hpp"

#include <cmath>
#include <cstdio>

namespace qd::app {

std::string format_duration(double s) {
  if (!std::isfinite(s) || s < 0) return "?";
  const auto t = static_cast<long long>(s + 0.5);
  char buf[32];
  if (t >= 3600)
    std::snprintf(buf, sizeof(buf), "%lldh%02lldm", t / 3600, (t / 60) % 60);
  else if (t >= 60)
    std::snprintf(buf, sizeof(buf), "%lldm%02llds", t / 60, t % 60);
  else
    std::snprintf(buf, sizeof(buf), "%llds", t);
  return buf;
}

std::string format_count(std::uint64_t n) {
  std::string s = std::to_string(n);
  for (int i = static_cast<int>(s.size()) - 3; i > 0; i -= 3) s.insert(static_cast<std::size_t>(i), ",");
  return s;
}

ProgressPrinter::ProgressPrinter(bool quiet, bool terminal, std::string label)
    : quiet_(quiet), terminal_(terminal), label_(std::move(label)) {}

void ProgressPrinter::operator()(const runtime::Progress& p) {
  if (quiet_) return;
  const double rate = p.wall_seconds > 0 ? static_cast<double>(p.session_evaluations) / p.wall_seconds : 0.0;
  const double eta = rate > 0 ? static_cast<double>(p.total_evaluations - p.evaluations) / rate : NAN;
  char line[512];
  std::snprintf(line, sizeof(line),
                "%s loop %d/%d | evals %s/%s | %.0f evals/s | coverage %.2f%% (%s cells) | ETA %s%s%s", label_.c_str(),
                p.loop, p.loops - 1, format_count(p.evaluations).c_str(), format_count(p.total_evaluations).c_str(),
                rate, 100.0 * p.coverage, format_count(p.elites).c_str(), format_duration(eta).c_str(),
                p.note.empty() ? "" : " | ", p.note.c_str());
  if (terminal_) {
    // Redraw at most ~10 times a second; always draw loop ends.
    if (!p.loop_finished && p.note.empty() && p.wall_seconds - last_draw_ < 0.1) return;
    last_draw_ = p.wall_seconds;
    std::fprintf(stderr, "\r\033[K%s", line);
    line_open_ = true;
  } else if (p.loop_finished) {
    std::fprintf(stderr, "%s\n", line);
  }
  std::fflush(stderr);
}

void ProgressPrinter::finish() {
  if (line_open_) std::fprintf(stderr, "\n");
  line_open_ = false;
}

}  // namespace qd::app
