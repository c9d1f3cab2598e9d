// What ends a run from outside the loop's own error handling never leaves its status "running".
//  * SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGUSR1/2, SIGALRM, SIGXCPU and the other signals whose
//    default action ends the process (unless the launcher ignored them, as nohup does SIGHUP): the
//    run stops at once, says where, and leaves a status that tells how to continue. Checkpoints
//    are committed atomically, so the last one is intact whatever the run was doing; --resume
//    continues from it (or starts again when there is none).
//  * SIGPIPE is ignored: a closed pipe on stdout or stderr takes the progress display, not the run.
//  * A fatal signal in qdrun's own process (SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT, SIGSYS,
//    SIGTRAP): plugin code that runs there (mutators, representations; rollouts and descriptors
//    with --backend threads) crashed. Status "failed: SIGSEGV in rollout() of environment 'x'
//    (/path/lib.so), after loop L iteration I; ...", the same line on stderr, then the signal's
//    default action (exit status 128 + the signal).
//  * exit() (or quick_exit()) while the run is under way, from plugin code in qdrun's own process:
//    status "failed: exit(C) called in ...", the line on stderr, exit code 3 (a plugin fault during
//    the run).
// Whichever thread gets to any of these first reports and ends the process; another thread that
// faults, exits or is signalled meanwhile waits for it: one report, one exit status.
// _exit() and SIGKILL cannot be intercepted; worker processes are supervised instead (issue 20).
#pragma once

#include <filesystem>
#include <vector>

namespace qd::app {

// The stop signals above (those whose default action ends qdrun without a word, the real-time
// signals included): what a run handles as SIGTERM, and what a sweep passes on to its runs.
std::vector<int> stop_signals();

// Installs the handlers for the run in `run_dir` (from the thread that drives the loop). On a stop
// signal: a newline if a live line is open on a terminal, one line on stderr, status "stopped by
// SIGNAL at loop L iteration I; resume with qdrun --resume DIR", exit 128 + the signal number
// (129, 130, 143, ...). Worker processes end with qdrun (they are killed when their parent dies).
// `handle_stop_signals` false: the stop signals are left to mpirun.
void guard_run(const std::filesystem::path& run_dir, bool terminal, bool handle_stop_signals);

// The run owns its directory (locked, checked, loaded; its status is about to say "running"):
// from now on the handlers write the status. Before, a stop signal ends qdrun with one line and
// leaves the directory as it was.
void own_run_directory() noexcept;

// The run is over (finished, stopped, or failed with an exception qdrun reports itself): exit()
// is qdrun's own again.
void end_of_run() noexcept;

// Where the run is, for the messages (called by the progress callback after every iteration).
void note_position(int loop, int iteration) noexcept;

}  // namespace qd::app
