// The evaluator gives identical results whatever the number of workers.
#include "runtime/evaluator.hpp"
#include "runtime/batch_protocol.hpp"
#include "runtime/process_evaluator.hpp"
#include "runtime/thread_evaluator.hpp"

#include <qd/descriptor.hpp>
#include <qd/environment.hpp>
#include <qd/policy.hpp>
#include <qd/rng.hpp>

#include <gtest/gtest.h>

#include <signal.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

using namespace qd;

namespace {
// A scripted environment, so the core's tests need no plugin: the policy sees the observation
// (step / 10, 0, ..., 0) for up to 50 steps and its first action is recorded; an episode ends
// early when that action leaves [-0.9, 0.9], and a non-finite action is kInvalidAction.
class ScriptedEnvironment final : public Environment {
 public:
  EnvironmentInfo info() const override { return {6, 3, 50}; }
  void rollout(const RolloutBatch& batch, Trace* traces) const override {
    Policy policy(*batch.shape);
    std::vector<float> obs(6, 0.0f);
    for (std::size_t i = batch.begin; i < batch.end; ++i) {
      Trace& t = traces[i];
      t.main.reset(1);
      policy.load(batch.row(i));
      for (int step = 0; step < 50; ++step) {
        obs[0] = static_cast<float>(step) / 10.0f;
        const double a = policy.act(obs.data())[0];
        if (!std::isfinite(a)) {
          t.status = EvalStatus::kInvalidAction;
          t.message = "non-finite action at step " + std::to_string(step);
          break;
        }
        t.main.push(a);
        t.fitness -= a * a;
        t.steps = step + 1;
        if (std::abs(a) > 0.9) break;
      }
    }
  }
};

// Bins the last recorded action over [-1, 1] into 50 cells.
class ScriptedDescriptor final : public Descriptor {
 public:
  GridSpec grid() const override { return {{50}, {"action"}, {-1.0}, {1.0}, 50}; }
  void describe(const Trace* traces, std::size_t n, std::int64_t* cells, double* values) const override {
    for (std::size_t i = 0; i < n; ++i) {
      const double a = traces[i].main.last()[0];
      cells[i] = static_cast<std::int64_t>(std::clamp(std::floor((a + 1.0) * 25.0), 0.0, 49.0));
      values[i] = a;
    }
  }
};
// Every per-offspring field of two evaluations is identical.
void expect_same(const runtime::Evaluations& a, const runtime::Evaluations& b) {
  EXPECT_EQ(a.cells, b.cells);
  EXPECT_EQ(a.descriptors, b.descriptors);
  EXPECT_EQ(a.fitness, b.fitness);
  EXPECT_EQ(a.steps, b.steps);
  EXPECT_EQ(a.status, b.status);
}

// `rows` policies of `shape` with parameters drawn from U(-1, 1).
Matrix random_params(const PolicyShape& shape, Eigen::Index rows, std::uint64_t seed) {
  Matrix params(rows, static_cast<Eigen::Index>(shape.param_count()));
  Rng rng(seed, Stream::kInitial);
  rng.fill_uniform(params.data(), static_cast<std::size_t>(params.size()), -1, 1);
  return params;
}
}  // namespace

TEST(Evaluator, OneAndThreeWorkersGiveIdenticalTracesAndCells) {
  const ScriptedEnvironment env;
  const ScriptedDescriptor desc;
  const PolicyShape shape(6, {8, 8}, 3);
  Matrix params = random_params(shape, 97, 11);
  params(5, 3) = std::nan("");  // a NaN action must give an invalid evaluation, not a crash
  std::vector<std::uint64_t> seeds(97, 0);
  runtime::ThreadEvaluator one(env, desc, shape, 1), three(env, desc, shape, 3);
  runtime::Evaluations a, b;
  one.evaluate(params, seeds, 0, a);
  three.evaluate(params, seeds, 0, b);
  expect_same(a, b);
  EXPECT_EQ(a.status[5], EvalStatus::kInvalidAction);
  EXPECT_EQ(a.cells[5], -1);
}

// The scripted answer: an all-zero policy acts 0 for 50 steps, cell 25, fitness 0.
TEST(Evaluator, ScriptedEnvironmentKnownAnswer) {
  const ScriptedEnvironment env;
  const ScriptedDescriptor desc;
  const PolicyShape shape(6, {8, 8}, 3);
  Matrix params = Matrix::Zero(1, static_cast<Eigen::Index>(shape.param_count()));
  std::vector<std::uint64_t> seeds(1, 0);
  runtime::ThreadEvaluator ev(env, desc, shape, 1);
  runtime::Evaluations out;
  ev.evaluate(params, seeds, 0, out);
  EXPECT_EQ(out.cells[0], 25);
  EXPECT_EQ(out.steps[0], 50);
  EXPECT_EQ(out.fitness[0], 0.0);
}

// Worker processes give exactly the thread backend's results, whatever the chunking.
TEST(Evaluator, ProcessesEqualThreads) {
  const ScriptedEnvironment env;
  const ScriptedDescriptor desc;
  const PolicyShape shape(6, {8, 8}, 3);
  Matrix params = random_params(shape, 131, 12);
  params(7, 2) = std::nan("");
  std::vector<std::uint64_t> seeds(131, 0);
  runtime::ThreadEvaluator serial(env, desc, shape, 1);
  runtime::ProcessEvaluator procs(env, desc, shape, 3, 131, 60);
  EXPECT_EQ(procs.workers(), 3);
  runtime::Evaluations a, b;
  serial.evaluate(params, seeds, 0, a);
  for (int round = 0; round < 2; ++round) {  // reused shared memory and workers
    procs.evaluate(params, seeds, 0, b);
    expect_same(a, b);
  }
  EXPECT_EQ(b.status[7], EvalStatus::kInvalidAction);
}

// Rows wider than the copy step (64 kB) reach the workers one at a time while they already run the
// first ones: every row is read only once it is copied, so a new batch never sees the last one's.
TEST(Evaluator, ProcessesReadEachRowOnlyOnceItIsCopied) {
  const ScriptedEnvironment env;
  const ScriptedDescriptor desc;
  const PolicyShape shape(6, {1500}, 3);  // 15 003 parameters: 120 kB per row
  ASSERT_GT(shape.param_count() * sizeof(double), std::size_t{64} << 10);
  runtime::ThreadEvaluator serial(env, desc, shape, 1);
  runtime::ProcessEvaluator procs(env, desc, shape, 2, 40, 60);
  std::vector<std::uint64_t> seeds(40, 0);
  for (std::uint64_t round = 0; round < 3; ++round) {
    const Matrix params = random_params(shape, 40, 100 + round);
    runtime::Evaluations a, b;
    serial.evaluate(params, seeds, 0, a);
    procs.evaluate(params, seeds, 0, b);
    expect_same(a, b);
  }
}

// A worker process that dies gives a WorkerFailure naming it, not a hang or a crash.
TEST(Evaluator, DeadWorkerProcessIsReported) {
  const ScriptedEnvironment env;
  const ScriptedDescriptor desc;
  const PolicyShape shape(6, {8, 8}, 3);
  Matrix params = Matrix::Zero(16, static_cast<Eigen::Index>(shape.param_count()));
  std::vector<std::uint64_t> seeds(16, 0);
  runtime::ProcessEvaluator procs(env, desc, shape, 2, 16, 60);
  ::kill(procs.worker_pid(1), SIGKILL);
  runtime::Evaluations out;
  try {
    procs.evaluate(params, seeds, 0, out);
    FAIL() << "expected a WorkerFailure";
  } catch (const runtime::WorkerFailure& e) {
    EXPECT_NE(std::string(e.what()).find("worker process 1 (pid"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("signal 9"), std::string::npos) << e.what();
  }
  EXPECT_THROW(procs.evaluate(params, seeds, 0, out), runtime::WorkerFailure);
}

namespace {
// The scripted environment, except that a policy whose first parameter is `kFaultMarker` makes
// rollout() throw, or (crash = true) raise SIGSEGV.
constexpr double kFaultMarker = 42.0;
class FaultyEnvironment final : public Environment {
 public:
  explicit FaultyEnvironment(bool crash = false) : crash_(crash) {}
  EnvironmentInfo info() const override { return inner_.info(); }
  void rollout(const RolloutBatch& batch, Trace* traces) const override {
    for (std::size_t i = batch.begin; i < batch.end; ++i)
      if (batch.row(i)[0] == kFaultMarker) {
        if (crash_) ::raise(SIGSEGV);
        throw std::runtime_error("deliberate fault");
      }
    inner_.rollout(batch, traces);
  }

 private:
  ScriptedEnvironment inner_;
  bool crash_;
};

const runtime::PluginLabels kLabels{"environment 'faulty' (test.so)", "descriptor 'scripted' (test.so)"};
}  // namespace

// Issue 20: an exception from a rollout on a worker thread is rethrown on the calling thread once
// every thread has left the job (it used to leave threads running a destroyed job: a use after
// free that AddressSanitizer reports), names the environment and the offspring, and leaves the
// pool usable.
TEST(Evaluator, ThreadsRethrowARolloutExceptionAfterEveryThreadStops) {
  const FaultyEnvironment env;
  const ScriptedDescriptor desc;
  const PolicyShape shape(6, {8, 8}, 3);
  Matrix params = random_params(shape, 300, 13);
  std::vector<std::uint64_t> seeds(300, 0);
  runtime::ThreadEvaluator threads(env, desc, shape, 4, kLabels);
  runtime::Evaluations out;
  for (int round = 0; round < 30; ++round) {
    const Eigen::Index bad = 7 + round * 9;
    params(bad, 0) = kFaultMarker;
    try {
      threads.evaluate(params, seeds, 0, out);
      FAIL() << "expected an EvaluationFault";
    } catch (const runtime::EvaluationFault& e) {
      EXPECT_EQ(e.first, static_cast<std::size_t>(bad));
      EXPECT_EQ(e.last, static_cast<std::size_t>(bad));
      EXPECT_STREQ(e.what(), "environment 'faulty' (test.so) threw from rollout(): deliberate fault");
    }
    params(bad, 0) = 0.5;
  }
  runtime::ThreadEvaluator serial(env, desc, shape, 1);
  runtime::Evaluations a;
  serial.evaluate(params, seeds, 0, a);
  threads.evaluate(params, seeds, 0, out);
  expect_same(a, out);
}

// The same exception in a worker process gives the same fault, message and offspring as in
// qdrun's own process.
TEST(Evaluator, WorkerProcessExceptionEqualsTheInProcessOne) {
  const FaultyEnvironment env;
  const ScriptedDescriptor desc;
  const PolicyShape shape(6, {8, 8}, 3);
  Matrix params = random_params(shape, 64, 14);
  params(37, 0) = kFaultMarker;
  std::vector<std::uint64_t> seeds(64, 0);
  std::string in_process;
  runtime::ThreadEvaluator serial(env, desc, shape, 1, kLabels);
  runtime::Evaluations out;
  try {
    serial.evaluate(params, seeds, 0, out);
  } catch (const runtime::EvaluationFault& e) {
    in_process = e.what();
    EXPECT_EQ(e.first, 37u);
  }
  EXPECT_FALSE(in_process.empty());
  for (int workers : {1, 2}) {
    runtime::ProcessEvaluator procs(env, desc, shape, workers, 64, 60, kLabels);
    try {
      procs.evaluate(params, seeds, 0, out);
      FAIL() << "expected an EvaluationFault";
    } catch (const runtime::EvaluationFault& e) {
      EXPECT_EQ(std::string(e.what()), in_process);
      EXPECT_EQ(e.first, 37u);
      EXPECT_EQ(e.last, 37u);
    }
  }
}

// A rollout that crashes its worker process is named with the signal, the environment and the
// exact offspring, and qdrun's process lives on.
TEST(Evaluator, CrashingRolloutNamesTheOffspring) {
  const FaultyEnvironment env(true);
  const ScriptedDescriptor desc;
  const PolicyShape shape(6, {8, 8}, 3);
  Matrix params = random_params(shape, 40, 15);
  params(23, 0) = kFaultMarker;
  std::vector<std::uint64_t> seeds(40, 0);
  runtime::ProcessEvaluator procs(env, desc, shape, 1, 40, 60, kLabels);
  runtime::Evaluations out;
  try {
    procs.evaluate(params, seeds, 0, out);
    FAIL() << "expected an EvaluationFault";
  } catch (const runtime::EvaluationFault& e) {
    EXPECT_EQ(e.first, 23u);
    EXPECT_NE(std::string(e.what()).find("worker process 1 (pid "), std::string::npos) << e.what();
#ifndef __SANITIZE_ADDRESS__  // AddressSanitizer turns the signal into its report and exit code 1
    EXPECT_NE(std::string(e.what()).find("killed by signal 11"), std::string::npos) << e.what();
#endif
    EXPECT_NE(std::string(e.what()).find("in rollout() of environment 'faulty' (test.so)"), std::string::npos)
        << e.what();
  }
}

// evaluate_rows, each MPI rank's path: blocks of rows give the whole batch's records, and a crash
// names the offspring by its index in the batch, after the caller's prefix (the rank).
TEST(Evaluator, ProcessRowBlocksEqualTheBatchAndNameTheOffspring) {
  const FaultyEnvironment env(true);
  const ScriptedDescriptor desc;
  const PolicyShape shape(6, {8, 8}, 3);
  Matrix params = random_params(shape, 40, 16);
  std::vector<std::uint64_t> seeds(40, 0);
  runtime::ThreadEvaluator serial(env, desc, shape, 1);
  runtime::Evaluations whole, blocks;
  serial.evaluate(params, seeds, 0, whole);
  runtime::ProcessEvaluator procs(env, desc, shape, 1, 16, 60, kLabels, "MPI rank 3 on node7: ");
  const std::size_t dims = desc.grid().shape.size();
  std::vector<double> records(16 * runtime::record_width(dims));
  blocks.reset(40, dims);
  for (std::size_t begin = 0; begin < 40; begin += 16) {
    const std::size_t rows = std::min<std::size_t>(16, 40 - begin);
    procs.evaluate_rows(params.row(static_cast<Eigen::Index>(begin)).data(), seeds.data() + begin, rows, records.data(),
                        begin);
    runtime::unpack_records(records.data(), begin, begin + rows, dims, blocks);
  }
  expect_same(whole, blocks);
  params(29, 0) = kFaultMarker;
  try {
    procs.evaluate_rows(params.row(16).data(), seeds.data() + 16, 16, records.data(), 16);
    FAIL() << "expected an EvaluationFault";
  } catch (const runtime::EvaluationFault& e) {
    EXPECT_EQ(e.first, 29u);
    EXPECT_EQ(e.last, 29u);
    EXPECT_EQ(std::string(e.what()).rfind("MPI rank 3 on node7: worker process 1 (pid ", 0), 0u) << e.what();
    EXPECT_NE(std::string(e.what()).find("in rollout() of environment 'faulty' (test.so)"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(procs.evaluate_rows(params.data(), seeds.data(), 1, records.data(), 0), runtime::WorkerFailure);
}

namespace {
// An environment with persistent worlds whose state is the history of its episodes: each world
// folds every row it runs into a running hash, and the trace reports the world and that hash. Any
// other order, a row in the wrong world or two rows of a world at once changes the answers.
class HistoryEnvironment final : public Environment {
 public:
  explicit HistoryEnvironment(int worlds) : state_(static_cast<std::size_t>(worlds), 0) {}
  EnvironmentInfo info() const override {
    EnvironmentInfo i{6, 3, 1};
    i.persistent_worlds = static_cast<int>(state_.size());
    return i;
  }
  void rollout(const RolloutBatch& batch, Trace* traces) const override {
    if (batch.world < 0 || batch.end - batch.begin != 1) throw std::logic_error("one row of one world per call");
    std::uint64_t& h = state_[static_cast<std::size_t>(batch.world)];
    const double first = batch.row(batch.begin)[0];
    std::uint64_t bits;
    std::memcpy(&bits, &first, sizeof bits);
    h = (h ^ bits) * 1099511628211ULL;  // FNV-style fold: order-sensitive
    Trace& t = traces[batch.begin];
    t.main.reset(1);
    t.main.push(0.0);
    t.steps = batch.world;
    t.fitness = static_cast<double>(h >> 12);
  }
  mutable std::vector<std::uint64_t> state_;  // touched by one thread per world (the core's promise)
};
}  // namespace

// Episode e runs in world e mod N, each world's episodes in order: the histories are the same with
// 1 or 3 threads, over batches that do not start at a multiple of N.
TEST(Evaluator, PersistentWorldsRunEachWorldsEpisodesInOrderWhateverTheThreads) {
  const ScriptedDescriptor desc;
  const PolicyShape shape(6, {4}, 3);
  const int worlds = 4;
  HistoryEnvironment env1(worlds), env3(worlds), reference(worlds);
  runtime::ThreadEvaluator one(env1, desc, shape, 1, {}, worlds), three(env3, desc, shape, 3, {}, worlds);
  std::uint64_t episode = 0;
  for (int batch = 0; batch < 3; ++batch) {
    const Eigen::Index n = 7 + 2 * batch;  // 7, 9, 11 rows: batches start at episodes 0, 7, 16
    const Matrix params = random_params(shape, n, 100 + batch);
    const std::vector<std::uint64_t> seeds(static_cast<std::size_t>(n), 0);
    runtime::Evaluations a, b;
    one.evaluate(params, seeds, episode, a);
    three.evaluate(params, seeds, episode, b);
    expect_same(a, b);
    // The same history computed by hand, sequentially in episode order.
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto e = episode + static_cast<std::uint64_t>(i);
      EXPECT_EQ(a.steps[static_cast<std::size_t>(i)], static_cast<std::int32_t>(e % worlds)) << "episode " << e;
      RolloutBatch b1{&shape,
                      params.data(),
                      seeds.data(),
                      static_cast<std::size_t>(i),
                      static_cast<std::size_t>(i) + 1,
                      static_cast<int>(e % worlds)};
      std::vector<Trace> traces(static_cast<std::size_t>(n));
      reference.rollout(b1, traces.data());
      EXPECT_EQ(a.fitness[static_cast<std::size_t>(i)], traces[static_cast<std::size_t>(i)].fitness) << "episode " << e;
    }
    episode += static_cast<std::uint64_t>(n);
  }
  EXPECT_EQ(env1.state_, reference.state_);
  EXPECT_EQ(env3.state_, reference.state_);
}

// Such an environment runs only in qdrun's process: "auto" picks threads, processes are refused
// naming the environment; the dry-run's pilot (fresh worlds) may use any backend.
TEST(Evaluator, PersistentWorldsNeedTheThreadsBackend) {
  const HistoryEnvironment env(2);
  const ScriptedDescriptor desc;
  const PolicyShape shape(6, {4}, 3);
  runtime::EvaluatorSpec spec;
  spec.labels.environment = "environment 'history'";
  spec.backend = runtime::Backend::kAuto;
  EXPECT_STREQ(runtime::make_evaluator(spec, env, desc, shape)->backend(), "threads");
  spec.backend = runtime::Backend::kProcesses;
  try {
    runtime::make_evaluator(spec, env, desc, shape);
    FAIL() << "processes accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("environment 'history' keeps 2 persistent worlds"), std::string::npos)
        << e.what();
  }
  spec.fresh_worlds = true;
  spec.workers = 1;
  spec.capacity = 4;
  EXPECT_STREQ(runtime::make_evaluator(spec, env, desc, shape)->backend(), "processes");
}

// The batch protocol (batch_protocol.hpp): the one row evaluator is what every backend runs, so a
// block of rows evaluated by it directly, one rollout call per row (as worker processes run it)
// or in one call, unpacks to what the threads and process backends return for the whole batch.
TEST(BatchProtocol, TheRowEvaluatorIsWhatEveryBackendRuns) {
  const ScriptedEnvironment env;
  const ScriptedDescriptor desc;
  const PolicyShape shape(6, {8, 8}, 3);
  Matrix params = random_params(shape, 37, 21);
  params(5, 0) = std::nan("");  // a failed rollout: status and steps travel, no cell
  std::vector<std::uint64_t> seeds(37);
  for (std::size_t i = 0; i < seeds.size(); ++i) seeds[i] = 1000 + i;
  runtime::ThreadEvaluator threads(env, desc, shape, 3);
  runtime::ProcessEvaluator procs(env, desc, shape, 2, 37, 60);
  runtime::Evaluations by_threads, by_processes, by_rows, by_single_rows;
  threads.evaluate(params, seeds, 0, by_threads);
  procs.evaluate(params, seeds, 0, by_processes);

  runtime::RowEvaluator rows(env, desc, shape);
  const std::size_t dims = rows.dims(), w = runtime::record_width(dims);
  std::vector<double> records(37 * w, -7.0);
  rows.run(params.data(), seeds.data(), 37, records.data());
  by_rows.reset(37, dims);
  runtime::unpack_records(records.data(), 0, 37, dims, by_rows);
  // Rows 10..19 alone, one rollout call each with the progress word, as a worker process runs them.
  std::atomic<std::uint64_t> current{99};
  std::vector<double> block(10 * w);
  rows.run(params.row(10).data(), seeds.data() + 10, 10, block.data(), 10, &current);
  EXPECT_EQ(current.load(), 0u);  // idle again
  by_single_rows = by_rows;
  runtime::unpack_records(block.data(), 10, 20, dims, by_single_rows);

  EXPECT_EQ(by_threads.status[5], EvalStatus::kInvalidAction);
  EXPECT_EQ(by_threads.cells[5], -1);
  expect_same(by_threads, by_processes);
  expect_same(by_threads, by_rows);
  expect_same(by_threads, by_single_rows);
}

// Records carry cells as doubles: exact for every cell a grid can have; a broken descriptor's cell
// beyond int64 saturates (no undefined conversion) and is still refused by the output checks.
TEST(BatchProtocol, RecordsRoundTripCellsAndSaturateBeyondInt64) {
  const std::size_t dims = 2, w = runtime::record_width(dims);
  std::vector<double> records(3 * w, 0.0);
  const double cells[3] = {static_cast<double>((std::int64_t{1} << 52) + 1), 1e30, -1e30};
  for (std::size_t i = 0; i < 3; ++i) {
    records[i * w + 0] = static_cast<double>(static_cast<int>(EvalStatus::kOk));
    records[i * w + 1] = 17;
    records[i * w + 2] = -0.25;
    records[i * w + 3] = cells[i];
    records[i * w + 4] = 0.5 + static_cast<double>(i);
    records[i * w + 5] = -1.5;
  }
  runtime::Evaluations out;
  out.reset(5, dims);
  runtime::unpack_records(records.data(), 2, 5, dims, out);
  EXPECT_EQ(out.cells[0], -1);  // rows before `begin` untouched
  EXPECT_EQ(out.cells[2], (std::int64_t{1} << 52) + 1);
  EXPECT_EQ(out.cells[3], std::numeric_limits<std::int64_t>::max());
  EXPECT_EQ(out.cells[4], std::numeric_limits<std::int64_t>::min());
  EXPECT_EQ(out.steps[3], 17);
  EXPECT_EQ(out.fitness[4], -0.25);
  EXPECT_EQ(out.descriptors(4, 0), 2.5);
  EXPECT_EQ(out.descriptors(4, 1), -1.5);
}

// Chunking is defined once: guided chunks never exceed the largest chunk, never drop below one
// row, shrink as the batch drains and cover it exactly.
TEST(BatchProtocol, GuidedChunksCoverTheBatchAndShrink) {
  for (const std::size_t n : {1u, 7u, 100u, 1000u, 4096u})
    for (const std::size_t workers : {1u, 2u, 3u, 16u}) {
      const std::size_t largest = runtime::largest_chunk(n, workers);
      EXPECT_GE(largest, 1u);
      EXPECT_LE(largest, std::max<std::size_t>(1, n / (8 * workers)));
      std::size_t done = 0, previous = largest;
      while (done < n) {
        const std::size_t c = std::min(runtime::guided_chunk(n - done, workers, largest), n - done);
        ASSERT_GE(c, 1u);
        ASSERT_LE(c, previous);
        previous = c;
        done += c;
      }
      EXPECT_EQ(done, n);
    }
}
