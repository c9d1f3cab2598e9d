// Sweeps, stage 3: execution (sweep_stages.hpp). The planned runs as child qdrun processes, a few
// at a time, each with its share of the cores; stop signals forwarded, every end reported.
#include "sweep_stages.hpp"

#include "run_guard.hpp"
#include "runtime/clock.hpp"
#include "runtime/evaluator.hpp"
#include "runtime/run_files.hpp"

#include <qd/errors.hpp>

#include <fcntl.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>
#include <algorithm>
#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <sstream>

namespace qd::app {
namespace fs = std::filesystem;
using runtime::Registry;

namespace {

std::string last_line(const fs::path& p) {
  std::istringstream in(read_text(p));
  std::string line, last;
  while (std::getline(in, line))
    if (!line.empty()) last = line;
  return last;
}

// A sweep stopped by a stop signal (SIGINT, SIGTERM, SIGHUP, SIGUSR1, ...: those a run handles as
// SIGTERM, run_guard.hpp) passes it on to its runs, so each stops as qdrun does alone (its status
// says where, --resume continues), waits for them and says so; no new run starts. A signal the
// sweep was started with ignored (nohup) stays ignored, for the runs too. Runs are tracked where
// the handler can read them (async-signal-safe). SIGPIPE is ignored.
constexpr std::size_t kMaxChildren = 4096;  // --jobs at most
std::atomic<pid_t> g_children[kMaxChildren];
volatile std::sig_atomic_t g_stop_signal = 0;
std::vector<int> g_forwarded;  // the signals the sweep forwards (set before any child starts)

void track_child(pid_t pid, bool running) {
  for (auto& c : g_children) {
    pid_t expected = running ? 0 : pid;
    if (c.compare_exchange_strong(expected, running ? pid : 0)) return;
  }
}

void on_sweep_stop(int sig) {
  g_stop_signal = sig;
  for (const auto& c : g_children)
    if (const pid_t pid = c.load(); pid > 0) ::kill(pid, sig);
}

struct StopForwarding {
  StopForwarding() {
    // A reader of the sweep's lines that goes away (qdrun ... | head) takes the lines, not the runs:
    // qdrun reports the lost output when the sweep ends (exit 4).
    if (struct sigaction now; ::sigaction(SIGPIPE, nullptr, &now) == 0 && now.sa_handler == SIG_DFL)
      ::signal(SIGPIPE, SIG_IGN);
    struct sigaction sa;
    std::memset(&sa, 0, sizeof(sa));
    sa.sa_handler = on_sweep_stop;
    sigemptyset(&sa.sa_mask);
    for (const int sig : stop_signals()) {
      struct sigaction now;
      if (::sigaction(sig, nullptr, &now) != 0 || (now.sa_flags & SA_SIGINFO) || now.sa_handler != SIG_DFL) continue;
      g_forwarded.push_back(sig);
      ::sigaction(sig, &sa, nullptr);
    }
  }
};

// Starts one child qdrun with its output appended to RUN_DIR/qdrun.log. The child gets SIGKILL
// when the sweep dies, so an interrupted sweep leaves no orphan runs writing into directories.
pid_t start_child(const std::string& exe, const std::vector<std::string>& args, const fs::path& log) {
  std::vector<char*> argv;
  argv.push_back(const_cast<char*>(exe.c_str()));
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  // Opened here, with the checks of every run directory file (a FIFO there would block the child,
  // a symlink or hard link send its output elsewhere): an error names it before anything starts.
  const int fd = runtime::open_for_update(log, O_APPEND, true);
  const pid_t parent = ::getpid();
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fd);
    throw SystemError(std::string("cannot start a run: fork failed: ") + std::strerror(errno));
  }
  if (pid == 0) {
    for (const int sig : g_forwarded) ::signal(sig, SIG_DFL);  // not the sweep's forwarding; ignored ones stay so
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (::getppid() != parent) ::_exit(127);  // the sweep died before prctl took effect
    ::dup2(fd, STDOUT_FILENO);
    ::dup2(fd, STDERR_FILENO);
    ::execv(exe.c_str(), argv.data());
    std::fprintf(stderr, "qdrun sweep: cannot execute %s: %s\n", exe.c_str(), std::strerror(errno));
    ::_exit(127);
  }
  ::close(fd);
  return pid;
}

}  // namespace

int run_sweep(const SweepOptions& o,
              const std::function<void(Registry&, const std::vector<std::string>&)>& setup_registry) {
  if (o.experiments.empty()) throw InputError("no experiment file given");
  if (o.jobs < 0 || o.workers < 0) throw InputError("--jobs and --workers must be >= 0");
  if (o.evaluations >= 0)
    for (const auto& s : o.sets)
      if (s.rfind("experiment.loops=", 0) == 0) throw InputError("--evaluations and --set experiment.loops conflict");
  for (const auto& s : o.optional_sets)
    if (s.find('=') == std::string::npos) throw InputError("--set-optional " + s + ": expected KEY=VALUE");

  // Plan and check every run before starting any: bad input anywhere stops the sweep here.
  RegistryCache regs(setup_registry);
  std::vector<PlannedRun> runs = plan_sweep(o, regs);

  const int hw = runtime::hardware_workers();
  std::size_t todo = 0;
  for (const auto& r : runs) todo += r.action != Action::kSkip;
  const int jobs = o.jobs > 0 ? o.jobs : hw;
  const int concurrent =
      static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(jobs), std::max<std::size_t>(todo, 1)));
  // Cores are shared among the runs that run at once; results do not depend on the worker count.
  const int workers = o.workers > 0 ? o.workers : std::max(1, hw / concurrent);
  std::printf("sweep: %zu runs (%zu to do, %zu complete), %d at a time, %d worker%s each\n", runs.size(), todo,
              runs.size() - todo, concurrent, workers, workers == 1 ? "" : "s");
  const std::string exe = fs::read_symlink("/proc/self/exe").string();

  std::size_t skipped = 0, finished = 0;
  std::vector<std::string> failed;
  const std::size_t width = std::to_string(runs.size()).size();
  auto tag = [&](std::size_t i) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "[%*zu/%zu]", static_cast<int>(width), i + 1, runs.size());
    return std::string(buf);
  };
  std::vector<std::size_t> pending;
  for (std::size_t i = 0; i < runs.size(); ++i) {
    if (runs[i].action == Action::kSkip) {
      ++skipped;
      std::printf("%s skip   %s (%s)\n", tag(i).c_str(), runs[i].label.c_str(), runs[i].why.c_str());
    } else {
      pending.push_back(i);
      if (o.dry_run)
        std::printf("%s plan   %s (%s): qdrun", tag(i).c_str(), runs[i].label.c_str(), runs[i].why.c_str());
      if (o.dry_run) {
        for (const auto& a : runs[i].child) std::printf(" %s", a.c_str());
        std::printf("\n");
      }
    }
  }
  std::fflush(stdout);
  if (o.dry_run) {
    print_cost_estimate(o, runs, pending, regs, concurrent, workers, hw);
    return 0;
  }

  // Each run's OpenMP threads (the autoencoder's training) stay within its share of the cores:
  // concurrent runs that each train on every core spin-wait on each other's threads, which made
  // two concurrent Walker fits 3 times slower (docs/performance-history.md). Results do not depend on it.
  if (std::getenv("OMP_THREAD_LIMIT") == nullptr) ::setenv("OMP_THREAD_LIMIT", std::to_string(workers).c_str(), 1);
  std::map<pid_t, std::pair<std::size_t, double>> running;  // pid -> (run, start time)
  const StopForwarding stop_forwarding;
  std::size_t next = 0, stopped = 0;
  while (next < pending.size() || !running.empty()) {
    while (next < pending.size() && static_cast<int>(running.size()) < concurrent && !g_stop_signal) {
      const std::size_t i = pending[next++];
      PlannedRun& r = runs[i];
      // What a run that died before its first checkpoint left (Action::kRestart) is removed by the
      // run itself, under its lock: another qdrun may have taken the directory since it was
      // planned (two sweeps of one output directory), and its files are not the sweep's to delete.
      std::vector<std::string> args = r.child;
      args.insert(args.end(), {"--workers", std::to_string(workers)});  // per-loop lines go to the log
      for (const auto& p : o.plugin_paths) args.insert(args.end(), {"--plugin-path", p});
      pid_t pid = -1;
      try {
        check_unchanged(o, r, regs);
        std::error_code ec;
        fs::create_directories(r.dir, ec);
        if (ec) throw InputError("cannot create the run directory " + r.dir.string() + ": " + ec.message());
        pid = start_child(exe, args, r.dir / "qdrun.log");
      } catch (const Error& e) {
        // This run cannot start (its directory changed since it was planned, no process left):
        // the others go on, and the sweep ends with the runs that failed.
        failed.push_back(r.label);
        std::printf("%s FAILED %s: cannot start it: %s\n", tag(i).c_str(), r.label.c_str(), e.what());
        std::fflush(stdout);
        continue;
      }
      running[pid] = {i, runtime::now_seconds()};
      track_child(pid, true);
      std::printf("%s start  %s (%s)\n", tag(i).c_str(), r.label.c_str(), r.why.c_str());
      std::fflush(stdout);
    }
    if (running.empty()) {
      if (g_stop_signal) break;  // stopped between two runs: none is left to wait for
      continue;                  // every run left failed to start
    }
    int wstatus = 0;
    const pid_t pid = ::waitpid(-1, &wstatus, 0);
    if (pid < 0) {
      if (errno == EINTR) continue;
      throw Error(std::string("waitpid failed: ") + std::strerror(errno));
    }
    const auto it = running.find(pid);
    if (it == running.end()) continue;
    track_child(pid, false);
    const auto [i, t0] = it->second;
    running.erase(it);
    const PlannedRun& r = runs[i];
    const double seconds = runtime::now_seconds() - t0;
    const std::string status = read_text(r.dir / "status");
    if (WIFEXITED(wstatus) && WEXITSTATUS(wstatus) == 0 && status.rfind("complete", 0) == 0) {
      ++finished;
      std::printf("%s done   %s in %.1f s\n", tag(i).c_str(), r.label.c_str(), seconds);
    } else if (g_stop_signal && ((WIFEXITED(wstatus) && WEXITSTATUS(wstatus) == 128 + g_stop_signal) ||
                                 (WIFSIGNALED(wstatus) && WTERMSIG(wstatus) == g_stop_signal))) {
      ++stopped;
      std::printf("%s stop   %s after %.1f s: %s\n", tag(i).c_str(), r.label.c_str(), seconds,
                  status.substr(0, status.find('\n')).c_str());
    } else {
      failed.push_back(r.label);
      const std::string how = WIFEXITED(wstatus) ? "exit code " + std::to_string(WEXITSTATUS(wstatus))
                                                 : "killed by signal " + std::to_string(WTERMSIG(wstatus));
      std::printf("%s FAILED %s: %s after %.1f s: %s (log %s)\n", tag(i).c_str(), r.label.c_str(), how.c_str(), seconds,
                  last_line(r.dir / "qdrun.log").c_str(), (r.dir / "qdrun.log").c_str());
    }
    std::fflush(stdout);
  }
  if (g_stop_signal) {
    std::printf(
        "sweep: stopped by signal %d (%s): %zu runs finished, %zu stopped, %zu failed, %zu not started; run the same "
        "command again to finish the sweep\n",
        static_cast<int>(g_stop_signal), strsignal(g_stop_signal), finished, stopped, failed.size(),
        pending.size() - next);
    std::fflush(stdout);
    return 128 + g_stop_signal;
  }
  std::printf("sweep: %zu runs: %zu finished, %zu skipped (already complete), %zu failed\n", runs.size(), finished,
              skipped, failed.size());
  if (!failed.empty()) {
    std::printf("sweep: failed runs:");
    for (const auto& f : failed) std::printf(" %s", f.c_str());
    std::printf("\n");
  }
  std::fflush(stdout);
  return failed.empty() ? 0 : 1;
}

}  // namespace qd::app
