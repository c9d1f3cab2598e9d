#include "run_guard.hpp"

#include "runtime/plugin_call.hpp"

#include <fcntl.h>
#include <signal.h>
#include <stdlib.h>
#include <sys/syscall.h>
#include <unistd.h>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iterator>
#include <string>

namespace qd::app {
namespace {

constexpr int kExitPluginFault = 3;  // qdrun's exit code for a plugin fault during the run

// Everything the handlers use is prepared before they can run: they only format text and integers
// and call write, open, unlink, rename, access, sigaction, raise, pause and _exit
// (async-signal-safe).
char g_status_path[4096], g_status_tmp[4096], g_checkpoint[4096], g_run_dir[4096];
bool g_terminal = false;
std::atomic<bool> g_running{false};
// Whether the run owns its directory: before, a stop signal ends qdrun without touching the status
// (it may belong to another run, or say how an earlier session ended).
std::atomic<bool> g_owns_directory{false};
std::atomic<int> g_loop{0}, g_iteration{0};
// The thread that reports how the run ended (0: none yet). Whichever thread faults, exits or takes
// a stop signal first reports and ends the process; any other thread that gets there meanwhile
// waits for it, so two faults at once give one report and one exit status.
std::atomic<long> g_reporter{0};

long this_thread() noexcept {
  return ::syscall(SYS_gettid);
}

// True when the calling thread is to report how the run ended; false when it is reporting already
// (a fault or signal inside its own report). When another thread reports, waits for it to end the
// process and never returns.
bool take_report() noexcept {
  const long me = this_thread();
  long expected = 0;
  if (g_reporter.compare_exchange_strong(expected, me)) return true;
  if (expected == me) return false;
  for (;;) ::pause();
}

// Appends `text` at `at` (bounded by `end`); returns the new end.
char* put(char* at, char* end, const char* text) {
  while (text && *text && at < end) *at++ = *text++;
  return at;
}

char* put_int(char* at, char* end, int v) {
  char digits[16];
  int n = 0;
  if (v < 0 && at < end) *at++ = '-';
  unsigned u = v < 0 ? 0u - static_cast<unsigned>(v) : static_cast<unsigned>(v);
  do {
    digits[n++] = static_cast<char>('0' + u % 10);
    u /= 10;
  } while (u && n < 16);
  while (n > 0 && at < end) *at++ = digits[--n];
  return at;
}

// Writes `text` (ending in '\n') as the status and, prefixed with "qdrun: ", to stderr. The
// temporary file is made anew (O_EXCL, no symlink followed), as write_file_atomic does.
void report(char* text, char* at) {
  *at++ = '\n';
  if (!g_owns_directory.load()) {
    (void)!::write(STDERR_FILENO, "qdrun: ", 7);
    (void)!::write(STDERR_FILENO, text, static_cast<std::size_t>(at - text));
    return;
  }
  ::unlink(g_status_tmp);
  const int fd = ::open(g_status_tmp, O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0644);
  if (fd >= 0) {
    const bool ok = ::write(fd, text, static_cast<std::size_t>(at - text)) == at - text;
    ::close(fd);
    if (ok) ::rename(g_status_tmp, g_status_path);
  }
  if (g_terminal) (void)!::write(STDERR_FILENO, "\n", 1);
  (void)!::write(STDERR_FILENO, "qdrun: ", 7);
  (void)!::write(STDERR_FILENO, text, static_cast<std::size_t>(at - text));
}

bool has_checkpoint() noexcept {
  return ::access(g_checkpoint, F_OK) == 0;
}

// What the user does next, whatever stopped the run: --resume continues from the last checkpoint,
// or starts the run again when there is none (nothing to keep).
char* put_resume_hint(char* at, char* end) {
  at = put(at, end, "; resume with qdrun --resume ");
  at = put(at, end, g_run_dir);
  if (!has_checkpoint()) at = put(at, end, " (nothing was checkpointed yet: it starts again from loop 0)");
  return at;
}

// "<what> in mutate() of mutator 'iso' (/path/qd_basic.so), after loop L iteration I; <next>"
char* describe_fault(char* at, char* end, const char* what) {
  at = put(at, end, "failed: ");
  at = put(at, end, what);
  const runtime::PluginCall c = runtime::current_plugin_call();
  if (c.who && !c.own) {
    // Plugin code may run threads of its own (OpenMP training); the fault was in one of them, or
    // in another thread of qdrun's while the run was in this call.
    at = put(at, end, " in another thread while the run was in ");
    at = put(at, end, c.call);
    at = put(at, end, " of ");
    at = put(at, end, c.who);
  } else if (c.who) {
    at = put(at, end, " in ");
    at = put(at, end, c.call);
    at = put(at, end, " of ");
    at = put(at, end, c.who);
  } else {
    at = put(at, end, " outside plugin code");
  }
  at = put(at, end, ", after loop ");
  at = put_int(at, end, g_loop.load());
  at = put(at, end, " iteration ");
  at = put_int(at, end, g_iteration.load());
  if (has_checkpoint()) {
    at = put(at, end, "; the last checkpoint is intact: fix the cause and qdrun --resume ");
  } else {
    at = put(at, end, "; no checkpoint was written yet: fix the cause and start again (qdrun --resume ");
    at = put(at, end, g_run_dir);
    return put(at, end, " starts it from loop 0)");
  }
  return put(at, end, g_run_dir);
}

// The signals that would end qdrun without a word by their default action, and that a user, a
// terminal or a batch system sends to stop a job; they are handled as SIGTERM is. SIGPIPE is not
// among them: it is ignored during a run (guard_run).
constexpr int kStopSignals[] = {SIGHUP,  SIGINT,    SIGQUIT, SIGTERM, SIGUSR1, SIGUSR2,  SIGALRM,
                                SIGXCPU, SIGVTALRM, SIGPROF, SIGPOLL, SIGPWR,  SIGSTKFLT};

const char* stop_signal_name(int sig) {
  switch (sig) {
    case SIGHUP:
      return "SIGHUP";
    case SIGINT:
      return "SIGINT";
    case SIGQUIT:
      return "SIGQUIT";
    case SIGTERM:
      return "SIGTERM";
    case SIGUSR1:
      return "SIGUSR1";
    case SIGUSR2:
      return "SIGUSR2";
    case SIGALRM:
      return "SIGALRM";
    case SIGXCPU:
      return "SIGXCPU (CPU time limit)";
    case SIGVTALRM:
      return "SIGVTALRM";
    case SIGPROF:
      return "SIGPROF";
    case SIGPOLL:
      return "SIGPOLL";
    case SIGPWR:
      return "SIGPWR";
    case SIGSTKFLT:
      return "SIGSTKFLT";
    default:
      return "SIGRTMIN+";  // followed by its number
  }
}

// The signal's default action, from inside its handler: the exit status says which signal.
void die_by(int sig) {
  struct sigaction dfl;
  std::memset(&dfl, 0, sizeof(dfl));
  dfl.sa_handler = SIG_DFL;
  sigemptyset(&dfl.sa_mask);
  ::sigaction(sig, &dfl, nullptr);
  ::raise(sig);
}

void on_stop_signal(int sig) {
  if (!g_running.load()) return die_by(sig);  // the run is over: its status stays as it ended
  if (!take_report()) return;                 // this thread is reporting something else already: let it finish
  char text[4600];
  char* end = text + sizeof(text) - 2;
  char* at = put(text, end, "stopped by ");
  at = put(at, end, stop_signal_name(sig));
  if (sig >= SIGRTMIN && sig <= SIGRTMAX) at = put_int(at, end, sig - SIGRTMIN);
  if (g_owns_directory.load()) {
    at = put(at, end, " at loop ");
    at = put_int(at, end, g_loop.load());
    at = put(at, end, " iteration ");
    at = put_int(at, end, g_iteration.load());
    at = put_resume_hint(at, end);
  } else {
    at = put(at, end, " before the run started; ");
    at = put(at, end, g_run_dir);
    at = put(at, end, " is as it was");
  }
  report(text, at);
  ::_exit(128 + sig);
}

const char* signal_name(int sig) {
  switch (sig) {
    case SIGSEGV:
      return "SIGSEGV (segmentation fault)";
    case SIGBUS:
      return "SIGBUS (bus error)";
    case SIGFPE:
      return "SIGFPE (arithmetic exception)";
    case SIGILL:
      return "SIGILL (illegal instruction)";
    case SIGABRT:
      return "SIGABRT (abort)";
    case SIGSYS:
      return "SIGSYS (bad system call)";
    case SIGTRAP:
      return "SIGTRAP (trace trap)";
    default:
      return "a fatal signal";
  }
}

void on_fatal_signal(int sig) {
  // Not in a run, or a fault while reporting: straight to the default action.
  if (!g_running.load() || !take_report()) return die_by(sig);
  char text[9000];
  char* at = describe_fault(text, text + sizeof(text) - 2, signal_name(sig));
  report(text, at);
  die_by(sig);
}

// exit() called while the run is under way: only plugin code does that (qdrun ends the run before
// it returns from main). glibc runs each exit handler once, for the first thread that calls exit();
// a second thread that calls exit() meanwhile runs the next handler. So the handler is registered
// kExitHandlerCopies times: every thread that exits during a run meets one and waits for the first.
constexpr int kExitHandlerCopies = 32;

void on_exit_during_run(int code, void*) {
  if (!g_running.load() || !take_report()) return;
  char what[48];
  char* w = put(what, what + sizeof(what) - 9, "exit(");
  w = put_int(w, what + sizeof(what) - 9, code);
  w = put(w, what + sizeof(what) - 1, ") called");
  *w = '\0';
  char text[9000];
  char* at = describe_fault(text, text + sizeof(text) - 2, what);
  report(text, at);
  ::_exit(kExitPluginFault);
}

void on_quick_exit_during_run() {
  if (!g_running.load() || !take_report()) return;
  char text[9000];
  char* at = describe_fault(text, text + sizeof(text) - 2, "quick_exit() called");
  report(text, at);
  ::_exit(kExitPluginFault);
}

// Whether `sig` still has its default action (not ignored, as nohup leaves SIGHUP, nor handled by
// plugin code that installed a handler of its own).
bool has_default_action(int sig) {
  struct sigaction now;
  return ::sigaction(sig, nullptr, &now) == 0 && !(now.sa_flags & SA_SIGINFO) && now.sa_handler == SIG_DFL;
}

}  // namespace

std::vector<int> stop_signals() {
  std::vector<int> out(std::begin(kStopSignals), std::end(kStopSignals));
  for (int sig = SIGRTMIN; sig <= SIGRTMAX; ++sig) out.push_back(sig);
  return out;
}

void guard_run(const std::filesystem::path& run_dir, bool terminal, bool handle_stop_signals) {
  const std::string status = (run_dir / "status").string();
  std::snprintf(g_status_path, sizeof(g_status_path), "%s", status.c_str());
  std::snprintf(g_status_tmp, sizeof(g_status_tmp), "%s.tmp", status.c_str());
  std::snprintf(g_checkpoint, sizeof(g_checkpoint), "%s", (run_dir / "checkpoint.bin").c_str());
  std::snprintf(g_run_dir, sizeof(g_run_dir), "%s", run_dir.c_str());
  g_terminal = terminal;
  runtime::mark_run_thread();

  // A closed pipe on stdout or stderr (qdrun FILE 2>&1 | head -1) takes away the progress display,
  // not the run: writes to it fail (and are dropped) instead of killing qdrun.
  if (has_default_action(SIGPIPE)) ::signal(SIGPIPE, SIG_IGN);

  if (handle_stop_signals) {
    struct sigaction sa;
    std::memset(&sa, 0, sizeof(sa));
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    // One handler at a time: a second stop signal waits for the _exit.
    const std::vector<int> stops = stop_signals();
    for (const int sig : stops) sigaddset(&sa.sa_mask, sig);
    for (const int sig : stops)
      if (has_default_action(sig)) ::sigaction(sig, &sa, nullptr);
  }

  // A stack overflow in plugin code must still be reported: the handler gets its own stack.
  static char alternate_stack[64 * 1024];
  stack_t ss{};
  ss.ss_sp = alternate_stack;
  ss.ss_size = sizeof(alternate_stack);
  ::sigaltstack(&ss, nullptr);
  struct sigaction fatal;
  std::memset(&fatal, 0, sizeof(fatal));
  fatal.sa_handler = on_fatal_signal;
  // No SA_RESETHAND: the disposition is process-wide, and a second thread's fault must wait for
  // the first report instead of ending the process silently. The handler restores the default.
  fatal.sa_flags = SA_NODEFER | SA_ONSTACK;
  sigemptyset(&fatal.sa_mask);
  for (const int sig : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT, SIGSYS, SIGTRAP}) ::sigaction(sig, &fatal, nullptr);

  // Registered last, so they run before every other exit handler (the C++ runtime's, MPI's).
  static bool registered = false;
  if (!registered) {
    for (int i = 0; i < kExitHandlerCopies; ++i) {
      ::on_exit(on_exit_during_run, nullptr);
      std::at_quick_exit(on_quick_exit_during_run);
    }
    registered = true;
  }
  g_running.store(true);
}

void own_run_directory() noexcept {
  g_owns_directory.store(true);
}

void end_of_run() noexcept {
  g_running.store(false);
}

void note_position(int loop, int iteration) noexcept {
  g_loop.store(loop, std::memory_order_relaxed);
  g_iteration.store(iteration, std::memory_order_relaxed);
}

}  // namespace qd::app
