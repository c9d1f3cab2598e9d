// The one clock of the runtime: seconds on the monotonic clock, for timeouts, progress and the
// wall and training times a run records (never a source of randomness).
#pragma once

#include <chrono>

namespace qd::runtime {

inline double now_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace qd::runtime
