#include "interrupt.hpp"

#include <fcntl.h>
#include <unistd.h>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <string>

namespace qd::app {
namespace {

// Everything the handler uses is prepared before it can run: it only formats two integers and
// calls write, open, rename and _exit (async-signal-safe).
char g_status_path[4096], g_status_tmp[4096], g_resume_hint[4200];
bool g_terminal = false;
std::atomic<int> g_loop{0}, g_iteration{0};

// Appends `text` at `at` (bounded by `end`); returns the new end.
char* put(char* at, char* end, const char* text) {
  while (*text && at < end) *at++ = *text++;
  return at;
}

char* put_int(char* at, char* end, int v) {
  char digits[16];
  int n = 0;
  unsigned u = v < 0 ? 0u : static_cast<unsigned>(v);
  do {
    digits[n++] = static_cast<char>('0' + u % 10);
    u /= 10;
  } while (u && n < 16);
  while (n > 0 && at < end) *at++ = digits[--n];
  return at;
}

void on_signal(int sig) {
  char text[4600];
  char* end = text + sizeof(text) - 2;
  char* at = put(text, end, "stopped by ");
  at = put(at, end, sig == SIGINT ? "SIGINT" : "SIGTERM");
  at = put(at, end, " at loop ");
  at = put_int(at, end, g_loop.load());
  at = put(at, end, " iteration ");
  at = put_int(at, end, g_iteration.load());
  at = put(at, end, g_resume_hint);
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
  ::_exit(128 + sig);
}

}  // namespace

void stop_on_signals(const std::filesystem::path& run_dir, bool terminal) {
  const std::string status = (run_dir / "status").string();
  std::snprintf(g_status_path, sizeof(g_status_path), "%s", status.c_str());
  std::snprintf(g_status_tmp, sizeof(g_status_tmp), "%s.tmp", status.c_str());
  std::snprintf(g_resume_hint, sizeof(g_resume_hint), "; resume with qdrun --resume %s", run_dir.c_str());
  g_terminal = terminal;
  struct sigaction sa;
  std::memset(&sa, 0, sizeof(sa));
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaddset(&sa.sa_mask, SIGINT);  // one handler at a time: a second signal waits for the _exit
  sigaddset(&sa.sa_mask, SIGTERM);
  ::sigaction(SIGINT, &sa, nullptr);
  ::sigaction(SIGTERM, &sa, nullptr);
}

void note_position(int loop, int iteration) noexcept {
  g_loop.store(loop, std::memory_order_relaxed);
  g_iteration.store(iteration, std::memory_order_relaxed);
}

}  // namespace qd::app
