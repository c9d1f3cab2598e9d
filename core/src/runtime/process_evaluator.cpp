#include "runtime/process_evaluator.hpp"

#include "runtime/clock.hpp"

#include <poll.h>
#include <sched.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>
#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <new>
#include <string>

namespace qd::runtime {

namespace {

constexpr std::size_t kErrorBytes = 1024;
constexpr std::size_t kMaxWorkers = 4096;  // [evaluation] workers' upper bound

std::size_t round_up(std::size_t bytes) {
  return (bytes + 63) / 64 * 64;
}

// Why a reaped child ended, for the one-line error.
std::string describe_exit(int status) {
  if (WIFSIGNALED(status))
    return "was killed by signal " + std::to_string(WTERMSIG(status)) + " (" + strsignal(WTERMSIG(status)) + ")";
  if (WIFEXITED(status)) return "exited with code " + std::to_string(WEXITSTATUS(status));
  return "ended";
}

// In a worker process: exit() called by plugin code ends the process with its code at once. The
// handlers it would otherwise run (registered by qdrun, the C++ runtime and, under mpirun, MPI)
// belong to the parent, and MPI's would act on the parent's connections.
void exit_at_once(int code, void*) {
  ::_exit(code);
}

}  // namespace

struct ProcessEvaluator::Control {
  std::atomic<std::uint64_t> next{0};      // first row not yet claimed
  std::atomic<std::uint64_t> ready{0};     // rows whose parameters are in shared memory
  std::atomic<std::uint64_t> finished{0};  // rows done in this batch (progress, for the timeout)
  std::uint64_t rows = 0, workers = 1, largest = 1;
  std::uint64_t first = 0;  // offspring index of row 0 (evaluate_rows)
  std::atomic<int> error_owner{-1};
  std::uint64_t error_first = 0, error_last = 0;  // rows of an EvaluationFault
  bool error_has_rows = false;
  char error[kErrorBytes] = {0};
  // Per worker (1-based): what it evaluates now, RowEvaluator::progress_code, 0 = between offspring.
  std::atomic<std::uint64_t> current[kMaxWorkers + 1] = {};
};
static_assert(std::atomic<std::uint64_t>::is_always_lock_free, "shared counters must be lock-free");

ProcessEvaluator::ProcessEvaluator(const Environment& env, const Descriptor& desc, const PolicyShape& shape,
                                   int workers, std::size_t capacity, double timeout_seconds, PluginLabels labels,
                                   std::string where)
    : P_(shape.param_count()),
      dims_(desc.grid().dims()),
      width_(record_width(dims_)),
      capacity_(std::max<std::size_t>(capacity, 1)),
      timeout_(timeout_seconds),
      own_(env, desc, shape, std::move(labels)),
      where_(std::move(where)) {
  if (workers > static_cast<int>(kMaxWorkers))
    throw InputError("at most " + std::to_string(kMaxWorkers) + " worker processes");
  const std::size_t ctl_bytes = round_up(sizeof(Control));
  const std::size_t params_bytes = round_up(capacity_ * P_ * sizeof(double));
  const std::size_t seeds_bytes = round_up(capacity_ * sizeof(std::uint64_t));
  const std::size_t records_bytes = round_up(capacity_ * width_ * sizeof(double));
  map_bytes_ = ctl_bytes + params_bytes + seeds_bytes + records_bytes;
  map_ = ::mmap(nullptr, map_bytes_, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  if (map_ == MAP_FAILED)
    throw SystemError("cannot map " + std::to_string(map_bytes_) +
                      " bytes of shared memory for the worker processes: " + std::strerror(errno));
  auto* base = static_cast<char*>(map_);
  ctl_ = new (base) Control;
  params_ = reinterpret_cast<double*>(base + ctl_bytes);
  seeds_ = reinterpret_cast<std::uint64_t*>(base + ctl_bytes + params_bytes);
  records_ = reinterpret_cast<double*>(base + ctl_bytes + params_bytes + seeds_bytes);

  // Every socket pair exists before the first fork, so each child can close all ends but its own:
  // otherwise a sibling holding a copy would hide a dead worker's end of file.
  const auto n = static_cast<std::size_t>(std::max(workers, 1));
  std::vector<std::array<int, 2>> pairs(n);
  for (auto& p : pairs)
    if (::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, p.data()) != 0) {
      for (auto& q : pairs)
        if (&q != &p && q[0] > 0) ::close(q[0]), ::close(q[1]);
      ::munmap(map_, map_bytes_);
      throw SystemError(std::string("cannot create worker sockets: ") + std::strerror(errno));
    }
  const pid_t parent = ::getpid();
  for (std::size_t k = 0; k < n; ++k) {
    std::fflush(nullptr);  // no buffered output is written twice
    const pid_t pid = ::fork();
    if (pid == 0) {
      ::prctl(PR_SET_PDEATHSIG, SIGKILL);  // never outlive the parent
      if (::getppid() != parent) std::_Exit(0);
      for (std::size_t j = 0; j < n; ++j) {
        ::close(pairs[j][0]);
        if (j != k) ::close(pairs[j][1]);
      }
      child_main(static_cast<int>(k) + 1, pairs[k][1]);
    }
    if (pid < 0) {
      for (std::size_t j = k; j < n; ++j) ::close(pairs[j][0]), ::close(pairs[j][1]);
      shut_down();
      throw SystemError(std::string("cannot fork a worker process: ") + std::strerror(errno));
    }
    ::close(pairs[k][1]);
    children_.push_back({pid, pairs[k][0]});
  }
}

ProcessEvaluator::~ProcessEvaluator() {
  shut_down();
}

void ProcessEvaluator::shut_down() noexcept {
  // Workers hold no state worth flushing; a hung one would never read a polite request.
  for (auto& c : children_) {
    if (c.fd >= 0) ::close(c.fd);
    if (c.pid > 0) {
      ::kill(c.pid, SIGKILL);
      int st = 0;
      while (::waitpid(c.pid, &st, 0) < 0 && errno == EINTR) {
      }
    }
  }
  children_.clear();
  if (map_ && map_ != MAP_FAILED) ::munmap(map_, map_bytes_);
  map_ = nullptr;
}

void ProcessEvaluator::child_main(int w, int fd) {
  ::on_exit(exit_at_once, nullptr);  // registered last, so it runs first
  // A crash in plugin code takes the signal's default action: the parent names it in one line.
  // Handlers the parent installed for itself (MPI's backtrace printer) would bury that line.
  for (const int sig : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT}) ::signal(sig, SIG_DFL);
  try {
    RowEvaluator& ev = own_;  // this process's own copy
    for (;;) {
      char c = 0;
      const ssize_t r = ::recv(fd, &c, 1, 0);
      if (r < 0 && errno == EINTR) continue;
      if (r <= 0 || c == 'q') std::_Exit(0);
      char reply = 'd';
      try {
        work(w, ev);
      } catch (const std::exception& e) {
        int none = -1;
        if (ctl_->error_owner.compare_exchange_strong(none, w)) {
          std::strncpy(ctl_->error, e.what(), kErrorBytes - 1);
          const auto* fault = dynamic_cast<const EvaluationFault*>(&e);
          ctl_->error_has_rows = fault != nullptr;
          if (fault) ctl_->error_first = fault->first, ctl_->error_last = fault->last;
        }
        ctl_->current[w].store(0);
        reply = 'e';
      }
      if (::send(fd, &reply, 1, MSG_NOSIGNAL) != 1) std::_Exit(0);
    }
  } catch (...) {
  }
  // _Exit: the parent's destructors and atexit handlers belong to the parent.
  std::_Exit(1);
}

void ProcessEvaluator::work(int w, RowEvaluator& ev) {
  const std::size_t rows = ctl_->rows;
  for (;;) {
    std::uint64_t begin = ctl_->next.load();
    std::size_t count = 0;
    do {
      if (begin >= rows) return;
      // Only rows the parent has finished copying; it copies far faster than episodes run, so
      // this waits at most a few microseconds.
      std::uint64_t ready = ctl_->ready.load(std::memory_order_acquire);
      for (int spins = 0; ready <= begin; ready = ctl_->ready.load(std::memory_order_acquire))
        if (++spins % 64 == 0) ::sched_yield();
      count = std::min<std::size_t>(guided_chunk(rows - begin, ctl_->workers, ctl_->largest), ready - begin);
    } while (!ctl_->next.compare_exchange_weak(begin, begin + count));
    ev.run(params_ + begin * P_, seeds_ + begin, count, records_ + begin * width_, ctl_->first + begin,
           &ctl_->current[static_cast<std::size_t>(w)]);
    ctl_->finished.fetch_add(count);
  }
}

std::string ProcessEvaluator::doing(std::uint64_t current) const {
  if (current == 0) return "";
  const PluginLabels& l = own_.labels();
  return current % 2 == 1 ? " in describe() of " + l.descriptor : " in rollout() of " + l.environment;
}

void ProcessEvaluator::fail(const std::string& message, std::uint64_t current) {
  broken_ = true;
  shut_down();
  if (current == 0) throw WorkerFailure(message);
  const std::size_t row = current / 2 - 1;
  throw EvaluationFault(message, row, row);
}

void ProcessEvaluator::evaluate(const Matrix& params, const std::vector<std::uint64_t>& seeds,
                                std::uint64_t /*first_episode*/, Evaluations& out) {
  const auto n = static_cast<std::size_t>(params.rows());
  QD_CHECK(seeds.size() == n, "one episode seed per row");
  QD_CHECK(static_cast<std::size_t>(params.cols()) == P_, "parameter rows of the policy's size");
  if (broken_) throw WorkerFailure("the worker processes were shut down after an earlier failure");
  if (n > capacity_)
    throw Error("batch of " + std::to_string(n) + " rows exceeds the process backend's capacity of " +
                std::to_string(capacity_));
  out.reset(n, dims_);
  if (n == 0) return;
  run_batch(params.data(), seeds.data(), n, 0);
  unpack_records(records_, 0, n, dims_, out);
}

void ProcessEvaluator::evaluate_rows(const double* params, const std::uint64_t* seeds, std::size_t rows,
                                     double* records, std::size_t first_row) {
  if (broken_) throw WorkerFailure(where_ + "the worker processes were shut down after an earlier failure");
  if (rows > capacity_)
    throw Error("block of " + std::to_string(rows) + " rows exceeds the process backend's capacity of " +
                std::to_string(capacity_));
  if (rows == 0) return;
  run_batch(params, seeds, rows, first_row);
  std::copy(records_, records_ + rows * width_, records);
}

void ProcessEvaluator::run_batch(const double* params, const std::uint64_t* seeds, std::size_t n,
                                 std::size_t first_row) {
  ctl_->rows = n;
  ctl_->first = first_row;
  ctl_->workers = static_cast<std::size_t>(workers());
  ctl_->largest = largest_chunk(n, ctl_->workers);
  ctl_->finished.store(0);
  ctl_->next.store(0);
  ctl_->error_owner.store(-1);
  std::copy(seeds, seeds + n, seeds_);
  // The workers start once the first rows are in place and the rest are copied meanwhile: a
  // Striker batch (200 rows of 13 kB) takes about 1 ms to copy, 1 % of a run if workers waited.
  const std::size_t step = std::max<std::size_t>(1, (std::size_t{64} << 10) / (P_ * sizeof(double)));
  auto copy_until = [&](std::size_t end) {
    const std::size_t begin = ctl_->ready.load(std::memory_order_relaxed);
    std::copy(params + begin * P_, params + end * P_, params_ + begin * P_);
    ctl_->ready.store(end, std::memory_order_release);
  };
  ctl_->ready.store(0, std::memory_order_relaxed);
  copy_until(std::min(n, step));
  std::vector<std::size_t> pending;
  for (std::size_t k = 0; k < children_.size(); ++k) {
    const char go = 'g';
    // A failed send means the worker is gone; its end of file below names it.
    (void)::send(children_[k].fd, &go, 1, MSG_NOSIGNAL);
    pending.push_back(k);
  }
  for (std::size_t copied = std::min(n, step); copied < n;) copy_until(copied = std::min(n, copied + step));

  double last_progress = now_seconds();
  std::uint64_t last_finished = ctl_->finished.load();
  std::vector<pollfd> fds;
  while (!pending.empty()) {
    fds.clear();
    for (std::size_t k : pending) fds.push_back({children_[k].fd, POLLIN, 0});
    const int r = ::poll(fds.data(), fds.size(), 200);
    if (r < 0 && errno != EINTR) fail(where_ + "waiting for worker processes: " + std::strerror(errno));
    std::vector<std::size_t> still;
    for (std::size_t j = 0; j < pending.size(); ++j) {
      const std::size_t k = pending[j];
      if (r <= 0 || !(fds[j].revents & (POLLIN | POLLHUP | POLLERR))) {
        still.push_back(k);
        continue;
      }
      char c = 0;
      const ssize_t got = ::recv(children_[k].fd, &c, 1, 0);
      const std::string who =
          where_ + "worker process " + std::to_string(k + 1) + " (pid " + std::to_string(children_[k].pid) + ")";
      if (got <= 0) {
        int st = 0;
        const pid_t pid = children_[k].pid;
        while (::waitpid(pid, &st, 0) < 0 && errno == EINTR) {
        }
        children_[k].pid = -1;
        const std::uint64_t current = ctl_->current[k + 1].load();
        fail(who + " " + describe_exit(st) + (current ? doing(current) : " during an evaluation batch"), current);
      }
      if (c == 'e') {
        // The worker's own message, as the same exception reads in qdrun's process (read before
        // shut_down() unmaps it).
        const std::string error = ctl_->error;
        const bool has_rows = ctl_->error_has_rows;
        const std::size_t first = ctl_->error_first, last = ctl_->error_last;
        broken_ = true;
        shut_down();
        if (has_rows) throw EvaluationFault(error, first, last);
        throw WorkerFailure(who + ": " + error);
      }
    }
    pending.swap(still);
    const std::uint64_t f = ctl_->finished.load();
    if (f != last_finished) {
      last_finished = f;
      last_progress = now_seconds();
    } else if (timeout_ > 0 && !pending.empty() && now_seconds() - last_progress > timeout_) {
      // The hung worker is one in the middle of an offspring, if any is.
      std::size_t k = pending.front();
      for (std::size_t j : pending)
        if (ctl_->current[j + 1].load() != 0) {
          k = j;
          break;
        }
      const std::uint64_t current = ctl_->current[k + 1].load();
      fail(where_ + "worker process " + std::to_string(k + 1) + " (pid " + std::to_string(children_[k].pid) +
               ") made no progress for " + std::to_string(static_cast<long long>(timeout_)) +
               " s ([evaluation] timeout_seconds)" + doing(current) + "; it is hung or far too slow",
           current);
    }
  }
}

}  // namespace qd::runtime
