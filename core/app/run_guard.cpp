#include "run_guard.hpp"

#include "runtime/plugin_call.hpp"

#include <fcntl.h>
#include <signal.h>
#include <stdlib.h>
#include <unistd.h>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

namespace qd::app {
namespace {

constexpr int kExitPluginFault = 3;  // qdrun's exit code for a plugin fault during the run

// Everything the handlers use is prepared before they can run: they only format text and integers
// and call write, open, rename, access, sigaction, raise and _exit (async-signal-safe).
char g_status_path[4096], g_status_tmp[4096], g_checkpoint[4096], g_resume_hint[4200], g_run_dir[4096];
bool g_terminal = false;
std::atomic<bool> g_running{false};
std::atomic<int> g_loop{0}, g_iteration{0};
std::atomic_flag g_reporting = ATOMIC_FLAG_INIT;  // one report, whichever thread faults first

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

// Writes `text` (ending in '\n') as the status and, prefixed with "qdrun: ", to stderr.
void report(char* text, char* at) {
  *at++ = '\n';
  const int fd = ::open(g_status_tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd >= 0) {
    const bool ok = ::write(fd, text, static_cast<std::size_t>(at - text)) == at - text;
    ::close(fd);
    if (ok) ::rename(g_status_tmp, g_status_path);
  }
  if (g_terminal) (void)!::write(STDERR_FILENO, "\n", 1);
  (void)!::write(STDERR_FILENO, "qdrun: ", 7);
  (void)!::write(STDERR_FILENO, text, static_cast<std::size_t>(at - text));
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
  if (::access(g_checkpoint, F_OK) == 0) {
    at = put(at, end, "; the last checkpoint is intact: fix the cause and qdrun --resume ");
  } else {
    at = put(at, end, "; no checkpoint was written yet: fix the cause, delete ");
    at = put(at, end, g_run_dir);
    at = put(at, end, " and start again");
    return at;
  }
  return put(at, end, g_run_dir);
}

void on_stop_signal(int sig) {
  char text[4600];
  char* end = text + sizeof(text) - 2;
  char* at = put(text, end, "stopped by ");
  at = put(at, end, sig == SIGINT ? "SIGINT" : "SIGTERM");
  at = put(at, end, " at loop ");
  at = put_int(at, end, g_loop.load());
  at = put(at, end, " iteration ");
  at = put_int(at, end, g_iteration.load());
  at = put(at, end, g_resume_hint);
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
    default:
      return "a fatal signal";
  }
}

void on_fatal_signal(int sig) {
  // SA_RESETHAND restored the default action; a second fault while reporting goes straight to it.
  if (g_running.load() && !g_reporting.test_and_set()) {
    char text[9000];
    char* at = describe_fault(text, text + sizeof(text) - 2, signal_name(sig));
    report(text, at);
  }
  ::raise(sig);  // the default action now: the exit status says which signal
}

// exit() called while the run is under way: only plugin code does that (qdrun ends the run before
// it returns from main).
void on_exit_during_run(int code, void*) {
  if (!g_running.load() || g_reporting.test_and_set()) return;
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
  if (!g_running.load() || g_reporting.test_and_set()) return;
  char text[9000];
  char* at = describe_fault(text, text + sizeof(text) - 2, "quick_exit() called");
  report(text, at);
  ::_exit(kExitPluginFault);
}

}  // namespace

void guard_run(const std::filesystem::path& run_dir, bool terminal, bool handle_stop_signals) {
  const std::string status = (run_dir / "status").string();
  std::snprintf(g_status_path, sizeof(g_status_path), "%s", status.c_str());
  std::snprintf(g_status_tmp, sizeof(g_status_tmp), "%s.tmp", status.c_str());
  std::snprintf(g_checkpoint, sizeof(g_checkpoint), "%s", (run_dir / "checkpoint.bin").c_str());
  std::snprintf(g_run_dir, sizeof(g_run_dir), "%s", run_dir.c_str());
  std::snprintf(g_resume_hint, sizeof(g_resume_hint), "; resume with qdrun --resume %s", run_dir.c_str());
  g_terminal = terminal;
  runtime::mark_run_thread();

  if (handle_stop_signals) {
    struct sigaction sa;
    std::memset(&sa, 0, sizeof(sa));
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    sigaddset(&sa.sa_mask, SIGINT);  // one handler at a time: a second signal waits for the _exit
    sigaddset(&sa.sa_mask, SIGTERM);
    ::sigaction(SIGINT, &sa, nullptr);
    ::sigaction(SIGTERM, &sa, nullptr);
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
  fatal.sa_flags = SA_RESETHAND | SA_NODEFER | SA_ONSTACK;
  sigemptyset(&fatal.sa_mask);
  for (const int sig : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT}) ::sigaction(sig, &fatal, nullptr);

  // Registered last, so it runs before every other exit handler (the C++ runtime's, MPI's).
  ::on_exit(on_exit_during_run, nullptr);
  std::at_quick_exit(on_quick_exit_during_run);
  g_running.store(true);
}

void end_of_run() noexcept {
  g_running.store(false);
}

void note_position(int loop, int iteration) noexcept {
  g_loop.store(loop, std::memory_order_relaxed);
  g_iteration.store(iteration, std::memory_order_relaxed);
}

}  // namespace qd::app
