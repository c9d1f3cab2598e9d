// The MPI session of a qdrun process: MPI start and stop, this process's rank and the job's size,
// and rank 0's last word when mpirun ends the job. Without QD_WITH_MPI it reports a single process
// and mpi_start() is a no-op. The MPI backend itself (the batch traffic) is mpi_evaluator.cpp.
#pragma once

#include <signal.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace qd::runtime {

bool mpi_built() noexcept;
bool mpi_launched() noexcept;             // started by mpirun/mpiexec (environment variables)
void mpi_start(int* argc, char*** argv);  // MPI_Init when launched, else nothing
bool mpi_active() noexcept;               // MPI initialised
int mpi_rank() noexcept;
int mpi_size() noexcept;
// Rank 0: the worker ranks were told to stop and will finalise MPI, so rank 0 may finalise too and
// end with its own exit code (after a plugin fault, say) instead of making mpirun end the job.
bool mpi_workers_released() noexcept;
void mpi_stop() noexcept;  // MPI_Finalize when initialised
[[noreturn]] void mpi_abort(int code) noexcept;

// For the MPI evaluator (only with QD_WITH_MPI).
constexpr std::size_t kHostBytes = 64;
struct PeerInfo {  // one rank's process, gathered at start-up
  std::int64_t pid = 0;
  char host[kHostBytes] = {0};
};
// The worker ranks have the order to stop (mpi_workers_released() from now on).
void mpi_mark_workers_released() noexcept;
// Rank 0: on SIGTERM (OpenMPI's mpirun sends it when a rank dies, SIGKILL 1 s later), names the
// dead worker among `peers` (indexed by rank) on this host, writes "failed ..." to `status_file`
// (the checkpoint is untouched), prints one line and exits with code 3. `previous` receives the
// handler it replaces.
void mpi_report_termination(std::vector<PeerInfo> peers, const std::string& status_file, struct sigaction* previous);
// Rank `rank`'s process as gathered by mpi_report_termination (rank 0 only).
const PeerInfo& mpi_peer(int rank);

}  // namespace qd::runtime
