// What ends a run from outside the loop's own error handling never leaves its status "running".
//  * SIGINT and SIGTERM: the run stops at once, says where, and leaves a status that tells how to
//    continue. Checkpoints are committed atomically, so the last one is intact whatever the run was
//    doing; --resume continues from it.
//  * A fatal signal in qdrun's own process (SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT): plugin code
//    that runs there (mutators, representations; rollouts and descriptors with --backend threads)
//    crashed. Status "failed: SIGSEGV in rollout() of environment 'x' (/path/lib.so), after loop L
//    iteration I; ...", the same line on stderr, then the signal's default action (exit status
//    128 + the signal).
//  * exit() (or quick_exit()) while the run is under way, from plugin code in qdrun's own process:
//    status "failed: exit(C) called in ...", the line on stderr, exit code 3 (a plugin fault during
//    the run).
// _exit() and SIGKILL cannot be intercepted; worker processes are supervised instead (issue 20).
#pragma once

#include <filesystem>

namespace qd::app {

// Installs the handlers for the run in `run_dir` (from the thread that drives the loop). On
// SIGINT/SIGTERM: a newline if a live line is open on a terminal, one line on stderr, status
// "stopped by SIGNAL at loop L iteration I; resume with qdrun --resume DIR", exit 128 + the signal
// number (130, 143). Worker processes end with qdrun (they are killed when their parent dies).
// `handle_stop_signals` false: SIGINT and SIGTERM are left to mpirun.
void guard_run(const std::filesystem::path& run_dir, bool terminal, bool handle_stop_signals);

// The run is over (finished, stopped, or failed with an exception qdrun reports itself): exit()
// is qdrun's own again.
void end_of_run() noexcept;

// Where the run is, for the messages (called by the progress callback after every iteration).
void note_position(int loop, int iteration) noexcept;

}  // namespace qd::app
