// MPI backend (built with QD_WITH_MPI): rank 0 runs the loop and evaluates too; every other rank
// builds the same experiment and serves rank 0 (Run::serve).
//
// Per batch: rank 0 broadcasts the parameter rows and episode seeds (non-blocking collectives), then
// hands out row ranges on demand (guided: they shrink towards the end of the batch), keeping two in
// flight per worker so a worker never waits for rank 0, which evaluates ranges of the same sizes
// itself and answers between them (dynamic load balancing; only ranges and compact result records
// travel after the broadcast). Results go into per-offspring slots, so nothing depends on which rank
// evaluated what.
//
// Supervision: no plugin rollout or describe() runs in an MPI process. Every rank, rank 0 included,
// evaluates its rows in one worker process of its own (ProcessEvaluator::evaluate_rows), forked at
// start-up; that child never calls MPI. A rollout that crashes, aborts, calls exit(), throws or
// hangs past [evaluation] timeout_seconds is caught by the rank that ran it, which names the
// component, its library and the offspring. A worker rank sends the fault to rank 0 (a result
// record marked kFault, then the message under kTagFault) and answers any further range of the
// batch with kSkipped. Rank 0 stops handing out rows, lets every worker finish and acknowledge the
// batch, and throws the fault as the serial backend does (exit 3, status, fault-offspring.csv, the
// checkpoint kept); its destructor then releases the workers, which leave serve() and finalise MPI
// normally, so the job ends with rank 0's one line and code.
//
// Faults of a whole rank: OpenMPI's mpirun reacts to a dead rank by sending SIGTERM to the others
// (SIGKILL 1 s later). Rank 0 catches it (mpi_session.cpp), finds the dead worker among the pids gathered at
// start-up, writes the run's status file ("failed ...", the checkpoint is untouched) and exits with
// one line. A worker rank that sends nothing for twice [evaluation] timeout_seconds plus 5 s (its
// own supervision reports a hung rollout after timeout_seconds) is reported as hung and the job
// aborted. Waiting ranks poll with a growing sleep, so idle workers leave the cores to rank 0's
// training.
#include "runtime/mpi_evaluator.hpp"

#include "runtime/batch_protocol.hpp"
#include "runtime/clock.hpp"
#include "runtime/mpi_session.hpp"
#include "runtime/process_evaluator.hpp"

#include <mpi.h>

#include <signal.h>
#include <unistd.h>
#include <algorithm>
#include <chrono>
#include <climits>
#include <cstdlib>
#include <cstring>
#include <thread>

namespace qd::runtime {

namespace {

constexpr int kTagWork = 1, kTagResult = 2, kTagFault = 3;
// A result record's row count (its second value) is the number of rows evaluated (>= 1), 0 for the
// acknowledgement at the end of a batch, or one of these.
constexpr double kFault = -1;    // the range failed: has_rows, first, last follow; the message under kTagFault
constexpr double kSkipped = -2;  // not evaluated: this rank reported a fault earlier in the batch
constexpr std::size_t kFaultBytes = 4096;

// Polls: spins for 200 us (rank 0 between batches usually answers within that), then sleeps
// 50 us doubling to `longest`, so idle ranks leave the cores to rank 0's training. Transfers in
// progress use a short `longest`: each segment of a broadcast needs both sides inside MPI, and a
// spinning rank would steal the core of a peer that shares it.
class Backoff {
 public:
  explicit Backoff(int longest_us = 1000) : longest_(longest_us) {}
  void reset() {
    start_ = -1;
    us_ = std::min(50, longest_);
  }
  void pause() {
    const double now = now_seconds();
    if (start_ < 0) start_ = now;
    if (now - start_ < 200e-6) return;
    std::this_thread::sleep_for(std::chrono::microseconds(us_));
    us_ = std::min(us_ * 2, longest_);
  }

 private:
  int longest_;
  double start_ = -1;
  int us_ = 50;
};

void check(int rc, const char* what) {
  if (rc == MPI_SUCCESS) return;
  char text[MPI_MAX_ERROR_STRING];
  int len = 0;
  MPI_Error_string(rc, text, &len);
  throw WorkerFailure(std::string(what) + ": " + std::string(text, static_cast<std::size_t>(len)));
}

int as_count(std::size_t n) {
  if (n > static_cast<std::size_t>(INT_MAX)) throw Error("MPI message of " + std::to_string(n) + " elements");
  return static_cast<int>(n);
}

// "MPI rank 1 on node7: ", how messages name this rank's worker process.
std::string rank_label() {
  char host[kHostBytes] = {0};
  ::gethostname(host, kHostBytes - 1);
  return "MPI rank " + std::to_string(mpi_rank()) + " on " + host + ": ";
}

// A fault of a rank's worker process, as ProcessEvaluator reported it: an EvaluationFault for
// rows [first, last] of the batch, or a WorkerFailure (the worker failed between offspring).
struct RankFault {
  bool set = false, has_rows = false;
  std::size_t first = 0, last = 0;
  std::string message;

  [[noreturn]] void raise() const {
    if (has_rows) throw EvaluationFault(message, first, last);
    throw WorkerFailure(message);
  }
};

template <class F>
RankFault supervised(F&& evaluate) {
  try {
    evaluate();
  } catch (const EvaluationFault& e) {
    return {true, true, e.first, e.last, e.what()};
  } catch (const WorkerFailure& e) {
    return {true, false, 0, 0, e.what()};
  }
  return {};
}

// Rank 0 waits this long beyond twice timeout_seconds before it calls a silent worker rank hung:
// the rank's own supervision reports a hung rollout after timeout_seconds.
constexpr double kRankGrace = 5;

class MpiEvaluator final : public Evaluator {
 public:
  MpiEvaluator(const EvaluatorSpec& spec, const Environment& env, const Descriptor& desc, const PolicyShape& shape)
      : P_(shape.param_count()),
        dims_(desc.grid().dims()),
        width_(record_width(dims_)),
        timeout_(spec.timeout_seconds),
        rank_timeout_(spec.timeout_seconds > 0 ? 2 * spec.timeout_seconds + kRankGrace : 0),
        // Forked first, before the signal handlers below and any traffic of this evaluator; it
        // holds the largest range of a batch of `capacity` rows.
        own_(env, desc, shape, 1,
             largest_chunk(std::max<std::size_t>(spec.capacity, 1), static_cast<std::size_t>(mpi_size())),
             spec.timeout_seconds, spec.labels, rank_label()) {
    PeerInfo me;
    me.pid = ::getpid();
    ::gethostname(me.host, kHostBytes - 1);
    std::vector<PeerInfo> all(static_cast<std::size_t>(mpi_rank() == 0 ? mpi_size() : 0));
    check(MPI_Gather(&me, sizeof(PeerInfo), MPI_BYTE, all.data(), sizeof(PeerInfo), MPI_BYTE, 0, MPI_COMM_WORLD),
          "MPI start-up handshake");
    if (mpi_rank() == 0) {
      mpi_report_termination(std::move(all), spec.status_file, &previous_);
    } else {
      // mpirun sends SIGTERM to every rank when one dies; workers stay until its SIGKILL, so the
      // only dead worker rank 0 finds is the one that failed.
      struct sigaction sa {};
      sa.sa_handler = SIG_IGN;
      sigemptyset(&sa.sa_mask);
      ::sigaction(SIGTERM, &sa, &previous_);
    }
  }

  ~MpiEvaluator() override {
    if (mpi_rank() == 0 && !stopped_) {
      // Tell the workers to leave serve(); bounded, since a hung worker never joins the broadcast.
      // Once they have it, every rank may finalise MPI normally (mpi_workers_released).
      try {
        std::uint64_t hdr[2] = {0, 0};
        broadcast(hdr, 2, MPI_UINT64_T, 5.0);
        mpi_mark_workers_released();
      } catch (...) {
      }
    }
    ::sigaction(SIGTERM, &previous_, nullptr);
  }

  int workers() const noexcept override { return mpi_size(); }
  const char* backend() const noexcept override { return "mpi"; }

  void evaluate(const Matrix& params, const std::vector<std::uint64_t>& seeds, std::uint64_t /*first_episode*/,
                Evaluations& out) override {
    const auto n = static_cast<std::size_t>(params.rows());
    QD_CHECK(seeds.size() == n, "one episode seed per row");
    QD_CHECK(mpi_rank() == 0, "only rank 0 runs the loop");
    if (stopped_) throw WorkerFailure("the MPI workers were stopped after an earlier failure");
    out.reset(n, dims_);
    if (n == 0) return;
    const auto size = static_cast<std::size_t>(mpi_size());
    const std::size_t largest = largest_chunk(n, size);
    // Rank 0 drives the broadcasts to completion before it evaluates (a large broadcast moves in
    // segments, each needing rank 0 inside MPI). If a worker never joins, they stay in flight
    // after timeout_seconds and the per-worker timeout below names that worker.
    hdr_[0] = n;
    hdr_[1] = largest;
    MPI_Request bcast[3];
    check(MPI_Ibcast(hdr_, 2, MPI_UINT64_T, 0, MPI_COMM_WORLD, &bcast[0]), "MPI broadcast");
    check(MPI_Ibcast(const_cast<double*>(params.data()), as_count(n * P_), MPI_DOUBLE, 0, MPI_COMM_WORLD, &bcast[1]),
          "MPI broadcast");
    check(MPI_Ibcast(const_cast<std::uint64_t*>(seeds.data()), as_count(n), MPI_UINT64_T, 0, MPI_COMM_WORLD, &bcast[2]),
          "MPI broadcast");

    const double started = now_seconds();
    Backoff transfer(10);
    for (int done = 0; !done && (timeout_ <= 0 || now_seconds() - started < timeout_); transfer.pause())
      check(MPI_Testall(3, bcast, &done, MPI_STATUSES_IGNORE), "MPI broadcast");

    const std::size_t workers = size - 1;
    std::vector<std::vector<double>> inbox(workers, std::vector<double>(2 + largest * width_));
    std::vector<MPI_Request> recv(workers, MPI_REQUEST_NULL);
    std::vector<int> in_flight(workers, 0);
    std::vector<double> last_heard(workers, started);
    std::size_t next = 0, rows_done = 0;
    RankFault fault;  // the first fault of the batch; no rows are handed out after it
    auto post = [&](std::size_t w) {
      check(MPI_Irecv(inbox[w].data(), as_count(inbox[w].size()), MPI_DOUBLE, static_cast<int>(w + 1), kTagResult,
                      MPI_COMM_WORLD, &recv[w]),
            "MPI receive");
    };
    auto hand_out = [&](std::size_t w) {
      const std::size_t count = guided_chunk(n - next, size, largest);
      const long long range[2] = {static_cast<long long>(next), static_cast<long long>(count)};
      check(MPI_Send(range, 2, MPI_LONG_LONG, static_cast<int>(w + 1), kTagWork, MPI_COMM_WORLD), "MPI send");
      next += count;
      ++in_flight[w];
    };
    // A message of worker w has arrived: results, a fault or a skipped range (then the next receive
    // is posted), or the acknowledgement of the batch's end (false).
    auto receive = [&](std::size_t w) {
      const double* msg = inbox[w].data();
      last_heard[w] = now_seconds();
      if (msg[1] == 0) return false;
      --in_flight[w];
      if (msg[1] == kFault) {
        take_fault(w, msg, fault);
      } else if (msg[1] > 0) {
        const auto begin = static_cast<std::size_t>(msg[0]);
        const std::size_t end = begin + static_cast<std::size_t>(msg[1]);
        unpack_records(msg + 2, begin, end, dims_, out);
        rows_done += end - begin;
      }
      post(w);
      return true;
    };
    for (std::size_t w = 0; w < workers; ++w) {
      post(w);
      for (int q = 0; q < 2 && next < n; ++q) hand_out(w);
    }
    std::vector<int> ready(workers);
    auto service = [&] {
      if (workers == 0) return false;
      int count = 0, sent = 0;
      check(MPI_Testall(3, bcast, &sent, MPI_STATUSES_IGNORE), "MPI broadcast");
      check(MPI_Testsome(static_cast<int>(workers), recv.data(), &count, ready.data(), MPI_STATUSES_IGNORE),
            "MPI test");
      for (int j = 0; j < count; ++j) {
        const auto w = static_cast<std::size_t>(ready[j]);
        receive(w);
        if (!fault.set && next < n) hand_out(w);
      }
      return count > 0 && count != MPI_UNDEFINED;
    };
    std::vector<double> mine(largest * width_);
    Backoff backoff;
    while (rows_done < n && !fault.set) {
      if (next < n) {
        // Rank 0 takes ranges like the workers: its worker process is woken once per range, the
        // ranges shrink to single rows at the end of the batch, and it answers between ranges
        // while each worker still holds one.
        const std::size_t begin = next, count = guided_chunk(n - next, size, largest);
        next += count;
        fault = supervised([&] {
          own_.evaluate_rows(params.row(static_cast<Eigen::Index>(begin)).data(), seeds.data() + begin, count,
                             mine.data(), begin);
        });
        if (!fault.set) {
          unpack_records(mine.data(), begin, begin + count, dims_, out);
          rows_done += count;
        }
        service();
        continue;
      }
      if (service()) {
        backoff.reset();
        continue;
      }
      const double now = now_seconds();
      for (std::size_t w = 0; w < workers; ++w)
        if (in_flight[w] > 0 && rank_timeout_ > 0 && now - last_heard[w] > rank_timeout_) hung(static_cast<int>(w + 1));
      backoff.pause();
    }
    // End of batch: every worker finishes the ranges it holds (after a fault too, so no message is
    // left in flight) and acknowledges, which also consumes the receive still posted for it.
    for (std::size_t w = 0; w < workers; ++w) {
      const long long end[2] = {0, 0};
      check(MPI_Send(end, 2, MPI_LONG_LONG, static_cast<int>(w + 1), kTagWork, MPI_COMM_WORLD), "MPI send");
    }
    const double t0 = now_seconds();
    for (std::size_t w = 0; w < workers; ++w) {
      backoff.reset();
      for (;;) {
        int flag = 0;
        check(MPI_Test(&recv[w], &flag, MPI_STATUS_IGNORE), "MPI test");
        if (flag) {
          if (!receive(w)) break;
          backoff.reset();
          continue;
        }
        if (rank_timeout_ > 0 && now_seconds() - std::max(t0, last_heard[w]) > rank_timeout_)
          hung(static_cast<int>(w + 1));
        backoff.pause();
      }
    }
    // Every worker acknowledged, so every broadcast has arrived: this returns at once.
    check(MPI_Waitall(3, bcast, MPI_STATUSES_IGNORE), "MPI broadcast");
    if (fault.set) fault.raise();
  }

  void serve() override {
    if (mpi_rank() == 0) return;
    std::vector<double> params, outbox;
    std::vector<std::uint64_t> seeds;
    for (;;) {
      std::uint64_t hdr[2] = {0, 0};
      broadcast(hdr, 2, MPI_UINT64_T, 0);
      const std::size_t n = hdr[0], largest = hdr[1];
      if (n == 0) {
        stopped_ = true;
        return;
      }
      params.resize(n * P_);
      seeds.resize(n);
      // The data follows the header at once: poll closely, each segment needs this rank in MPI.
      broadcast(params.data(), n * P_, MPI_DOUBLE, 0, true);
      broadcast(seeds.data(), n, MPI_UINT64_T, 0, true);
      outbox.resize(std::max<std::size_t>(2 + largest * width_, 5));
      Backoff backoff;
      bool failed = false;  // this rank reported a fault in this batch
      for (;;) {
        long long range[2] = {0, 0};
        MPI_Request req = MPI_REQUEST_NULL;
        check(MPI_Irecv(range, 2, MPI_LONG_LONG, 0, kTagWork, MPI_COMM_WORLD, &req), "MPI receive");
        backoff.reset();
        for (int flag = 0;;) {
          check(MPI_Test(&req, &flag, MPI_STATUS_IGNORE), "MPI test");
          if (flag) break;
          backoff.pause();
        }
        const auto begin = static_cast<std::size_t>(range[0]), count = static_cast<std::size_t>(range[1]);
        outbox[0] = static_cast<double>(begin);
        outbox[1] = static_cast<double>(count);
        if (count == 0) {  // end of batch: acknowledge
          check(MPI_Send(outbox.data(), 2, MPI_DOUBLE, 0, kTagResult, MPI_COMM_WORLD), "MPI send");
          break;
        }
        QD_CHECK(begin + count <= n && count <= largest, "a row range inside the batch");
        if (failed) {
          outbox[1] = kSkipped;
          check(MPI_Send(outbox.data(), 2, MPI_DOUBLE, 0, kTagResult, MPI_COMM_WORLD), "MPI send");
          continue;
        }
        const RankFault fault = supervised([&] {
          own_.evaluate_rows(params.data() + begin * P_, seeds.data() + begin, count, outbox.data() + 2, begin);
        });
        if (fault.set) {
          report(outbox.data(), fault);
          failed = true;
          continue;
        }
        check(MPI_Send(outbox.data(), as_count(2 + count * width_), MPI_DOUBLE, 0, kTagResult, MPI_COMM_WORLD),
              "MPI send");
      }
    }
  }

 private:
  // A non-blocking broadcast from rank 0, polled; timeout 0 waits forever.
  void broadcast(void* data, std::size_t count, MPI_Datatype type, double timeout, bool transfer = false) {
    MPI_Request req = MPI_REQUEST_NULL;
    check(MPI_Ibcast(data, as_count(count), type, 0, MPI_COMM_WORLD, &req), "MPI broadcast");
    const double t0 = now_seconds();
    Backoff backoff(transfer ? 10 : 1000);
    for (int flag = 0;;) {
      check(MPI_Test(&req, &flag, MPI_STATUS_IGNORE), "MPI test");
      if (flag) return;
      if (timeout > 0 && now_seconds() - t0 > timeout) {
        stopped_ = true;
        throw WorkerFailure("an MPI worker rank did not join the batch broadcast for " +
                            std::to_string(static_cast<long long>(timeout)) +
                            " s ([evaluation] timeout_seconds); it is hung");
      }
      backoff.pause();
    }
  }

  // Worker rank: sends rank 0 the fault of the range outbox[0] begins: the record, then the message.
  static void report(double* outbox, const RankFault& f) {
    outbox[1] = kFault;
    outbox[2] = f.has_rows ? 1 : 0;
    outbox[3] = static_cast<double>(f.first);
    outbox[4] = static_cast<double>(f.last);
    check(MPI_Send(outbox, 5, MPI_DOUBLE, 0, kTagResult, MPI_COMM_WORLD), "MPI send");
    const std::size_t len = std::min(f.message.size(), kFaultBytes);
    check(MPI_Send(f.message.data(), as_count(len), MPI_CHAR, 0, kTagFault, MPI_COMM_WORLD), "MPI send");
  }

  // Rank 0: the message of the fault worker w announced in `record` (it follows at once); the
  // first fault of a batch is the one reported.
  static void take_fault(std::size_t w, const double* record, RankFault& fault) {
    char text[kFaultBytes];
    MPI_Status st;
    check(MPI_Recv(text, static_cast<int>(kFaultBytes), MPI_CHAR, static_cast<int>(w + 1), kTagFault, MPI_COMM_WORLD,
                   &st),
          "MPI receive");
    int len = 0;
    check(MPI_Get_count(&st, MPI_CHAR, &len), "MPI receive");
    if (fault.set) return;
    fault.set = true;
    fault.has_rows = record[2] != 0;
    fault.first = static_cast<std::size_t>(record[3]);
    fault.last = static_cast<std::size_t>(record[4]);
    fault.message.assign(text, static_cast<std::size_t>(std::max(len, 0)));
  }

  [[noreturn]] void hung(int rank) {
    stopped_ = true;
    const auto& p = mpi_peer(rank);
    throw WorkerFailure("MPI worker rank " + std::to_string(rank) + " (pid " + std::to_string(p.pid) + " on " + p.host +
                        ") made no progress for " + std::to_string(static_cast<long long>(timeout_)) +
                        " s ([evaluation] timeout_seconds) and reported no fault in " +
                        std::to_string(static_cast<long long>(rank_timeout_ - timeout_)) +
                        " s more; it is hung or far too slow");
  }

  std::size_t P_, dims_, width_;
  double timeout_, rank_timeout_;
  ProcessEvaluator own_;  // this rank's supervised worker process
  bool stopped_ = false;
  std::uint64_t hdr_[2] = {0, 0};  // broadcast buffer, alive while the batch runs
  struct sigaction previous_ {};
};

}  // namespace

std::unique_ptr<Evaluator> make_mpi_evaluator(const EvaluatorSpec& spec, const Environment& env, const Descriptor& desc,
                                              const PolicyShape& shape) {
  return std::make_unique<MpiEvaluator>(spec, env, desc, shape);
}

}  // namespace qd::runtime
