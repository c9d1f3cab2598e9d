// SIGINT and SIGTERM during a run: the run stops at once, says where, and leaves a status that
// tells how to continue. Checkpoints are committed atomically, so the last one is intact whatever
// the run was doing; --resume continues from it.
#pragma once

#include <filesystem>

namespace qd::app {

// Installs the handlers for the run in `run_dir`. On the first signal: a newline if a live line is
// open on a terminal, one line on stderr, status "stopped by SIGNAL at loop L iteration I; resume
// with qdrun --resume DIR", exit 128 + the signal number (130, 143). Worker processes end with
// qdrun (they are killed when their parent dies).
void stop_on_signals(const std::filesystem::path& run_dir, bool terminal);

// Where the run is, for the message (called by the progress callback).
void note_position(int loop, int iteration) noexcept;

}  // namespace qd::app
