#include "runtime/mpi_session.hpp"

#include <cstdlib>

#ifdef QD_WITH_MPI
#include <qd/errors.hpp>

#include <mpi.h>

#include <fcntl.h>
#include <unistd.h>
#include <cerrno>
#include <cstdio>
#include <cstring>
#endif

namespace qd::runtime {

#ifdef QD_WITH_MPI
namespace {

constexpr int kExitWorkerFailure = 3;

bool g_initialised = false, g_released = false;
int g_rank = 0, g_size = 1;

// Read by the SIGTERM handler of rank 0: plain arrays, filled before the handler is installed.
std::vector<PeerInfo> g_peers;
char g_status_file[4096] = {0};
char g_status_tmp[4200] = {0};
char g_run_dir[4096] = {0};

// Async-signal-safe helpers for the handler.
void put(char* buf, std::size_t cap, std::size_t& len, const char* s) {
  while (*s && len + 1 < cap) buf[len++] = *s++;
  buf[len] = 0;
}
void put_int(char* buf, std::size_t cap, std::size_t& len, long long v) {
  char digits[24];
  int n = 0;
  if (v < 0) {
    put(buf, cap, len, "-");
    v = -v;
  }
  do {
    digits[n++] = static_cast<char>('0' + v % 10);
    v /= 10;
  } while (v > 0 && n < 23);
  char out[24];
  for (int i = 0; i < n; ++i) out[i] = digits[n - 1 - i];
  out[n] = 0;
  put(buf, cap, len, out);
}

void on_sigterm(int) {
  int dead = -1;
  for (std::size_t r = 1; r < g_peers.size(); ++r)
    if (std::strncmp(g_peers[r].host, g_peers[0].host, kHostBytes) == 0 &&
        ::kill(static_cast<pid_t>(g_peers[r].pid), 0) != 0 && errno == ESRCH) {
      dead = static_cast<int>(r);
      break;
    }
  char what[512];
  std::size_t wl = 0;
  if (dead > 0) {
    put(what, sizeof(what), wl, "MPI worker rank ");
    put_int(what, sizeof(what), wl, dead);
    put(what, sizeof(what), wl, " (pid ");
    put_int(what, sizeof(what), wl, g_peers[static_cast<std::size_t>(dead)].pid);
    put(what, sizeof(what), wl, " on ");
    put(what, sizeof(what), wl, g_peers[static_cast<std::size_t>(dead)].host);
    put(what, sizeof(what), wl, ") died and mpirun ended the job");
  } else {
    put(what, sizeof(what), wl,
        "terminated by SIGTERM (mpirun does this when a rank on another host dies, or the job was cancelled)");
  }
  char status[1024];
  std::size_t sl = 0;
  put(status, sizeof(status), sl, "failed: ");
  put(status, sizeof(status), sl, what);
  put(status, sizeof(status), sl, " (the last checkpoint is intact; fix the cause and --resume)\n");
  const int fd = ::open(g_status_tmp, O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd >= 0) {
    if (::write(fd, status, sl) == static_cast<ssize_t>(sl)) ::rename(g_status_tmp, g_status_file);
    ::close(fd);
  }
  char line[1024 + 4096];
  std::size_t ll = 0;
  put(line, sizeof(line), ll, "qdrun: error: ");
  put(line, sizeof(line), ll, what);
  put(line, sizeof(line), ll, "; the last checkpoint is intact: qdrun --resume ");
  put(line, sizeof(line), ll, g_run_dir);
  put(line, sizeof(line), ll, "\n");
  if (::write(STDERR_FILENO, line, ll) < 0) {
  }
  ::_exit(kExitWorkerFailure);
}

}  // namespace

bool mpi_built() noexcept {
  return true;
}

bool mpi_launched() noexcept {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE"})
    if (std::getenv(v)) return true;
  return false;
}

void mpi_start(int* argc, char*** argv) {
  if (!mpi_launched() || g_initialised) return;
  int provided = 0;
  // Funneled: representations may train with OpenMP threads, but only the main thread calls MPI.
  if (MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS) throw Error("MPI_Init_thread failed");
  g_initialised = true;
  MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
  MPI_Comm_rank(MPI_COMM_WORLD, &g_rank);
  MPI_Comm_size(MPI_COMM_WORLD, &g_size);
}

bool mpi_active() noexcept {
  return g_initialised;
}
bool mpi_workers_released() noexcept {
  return g_released;
}
int mpi_rank() noexcept {
  return g_rank;
}
int mpi_size() noexcept {
  return g_size;
}

void mpi_stop() noexcept {
  int finalized = 0;
  MPI_Finalized(&finalized);
  if (g_initialised && !finalized) MPI_Finalize();
}

void mpi_abort(int code) noexcept {
  if (g_initialised) MPI_Abort(MPI_COMM_WORLD, code);
  std::_Exit(code);
}

void mpi_mark_workers_released() noexcept {
  g_released = true;
}

void mpi_report_termination(std::vector<PeerInfo> peers, const std::string& status_file, struct sigaction* previous) {
  g_peers = std::move(peers);
  const std::string dir = status_file.substr(0, status_file.rfind('/'));
  std::snprintf(g_status_file, sizeof(g_status_file), "%s", status_file.c_str());
  std::snprintf(g_status_tmp, sizeof(g_status_tmp), "%s.tmp", status_file.c_str());
  std::snprintf(g_run_dir, sizeof(g_run_dir), "%s", dir.c_str());
  struct sigaction sa {};
  sa.sa_handler = on_sigterm;
  sigemptyset(&sa.sa_mask);
  ::sigaction(SIGTERM, &sa, previous);
}

const PeerInfo& mpi_peer(int rank) {
  return g_peers.at(static_cast<std::size_t>(rank));
}

#else
bool mpi_built() noexcept {
  return false;
}
bool mpi_launched() noexcept {
  return false;
}
void mpi_start(int*, char***) {}
bool mpi_active() noexcept {
  return false;
}
int mpi_rank() noexcept {
  return 0;
}
int mpi_size() noexcept {
  return 1;
}
bool mpi_workers_released() noexcept {
  return false;
}
void mpi_stop() noexcept {}
void mpi_abort(int code) noexcept {
  std::_Exit(code);
}
void mpi_mark_workers_released() noexcept {}
void mpi_report_termination(std::vector<PeerInfo>, const std::string&, struct sigaction*) {}
const PeerInfo& mpi_peer(int) {
  static const PeerInfo none;
  return none;
}
#endif

}  // namespace qd::runtime
