// Human-facing progress output of qdrun: a live line on a terminal, plain lines otherwise.
#pragma once

#include "runtime/run.hpp"

#include <string>

namespace qd::app {

class ProgressPrinter {
 public:
  ProgressPrinter(bool quiet, bool terminal, std::string label);
  void operator()(const runtime::Progress& p);
  void finish();

 private:
  bool quiet_, terminal_;
  std::string label_;
  bool line_open_ = false;
  double last_draw_ = -1.0;
};

std::string format_duration(double seconds);
std::string format_count(std::uint64_t n);

}  // namespace qd::app
