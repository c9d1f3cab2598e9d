// Conformance checks for plugin authors: the contract of every environment, descriptor,
// representation and mutator (the prose in its interface header), run as a test.
//
// Use them from your plugin's own tests, with any test framework:
//
//   #include <qd/testing/conformance.hpp>
//
//   TEST(MyEnvironment, Conforms) {
//     MyEnvironment env(qd::defaults_of(kMyParams, "environment"), qd::BuildContext{});
//     const qd::testing::Report report = qd::testing::check_environment(env);
//     EXPECT_TRUE(report.ok()) << report;
//   }
//
// Each check returns a Report: no failures when the component keeps its contract, otherwise one
// line per broken rule, naming the rule and the first rows where it broke. The checks throw
// nothing of their own; an exception from the component is a reported failure. (They are plain
// functions rather than GoogleTest assertions so that any framework, or a plain main(), can run
// them, and so that the installed core does not need GoogleTest.) What they check:
//
//  * check_environment: info() sizes are positive; one thread and several threads on disjoint
//    ranges give identical traces; no qd::Policy object is loaded on two threads (a Policy shared
//    between rollout() calls, which races only when calls overlap: found every time, whatever the
//    timing, as the threads take turns while the core watches Policy::load); a second run repeats
//    the traces; a range [begin, end) fills exactly those rows (the others are untouched) and
//    equals the same rows of the whole batch; statuses are valid, failed ones carry a message; the
//    trajectories of kOk traces are finite.
//  * check_descriptor: the grid is consistent (per-dimension sizes and bounds, cells = product of
//    the shape, as the core requires) and fixed; cells lie in [0, cells) or are -1; described
//    values are finite; results repeat and do not depend on threads or on how the traces are split.
//  * check_representation: after fit() on your dataset, encode/decode give N × LD and N × P finite
//    results; decoder_jacobians agree with central differences of decode; decoder_vjp with vᵀJ;
//    reconstruction_errors with ‖θ − Dec(Enc(θ))‖; two fresh models fitted alike save the same
//    state; save/load round-trips bit for bit (outputs and the saved blob) and a truncated blob
//    throws qd::StateError; the const members give the same results from several threads at once.
//  * check_mutator: offspring are count × P and finite, has_latent has count entries of 0 or 1
//    and marks finite latent rows, metrics match metric_names(), the mixing ratio is in [0, 1] or
//    NaN; two fresh mutators given the same inputs and Rng seeds (begin_loop, then mutate and
//    feedback for a few iterations) agree bit for bit; a state saved at the loop boundary and
//    loaded into a fresh mutator saves the same blob and gives the same next loop; a truncated
//    state throws qd::StateError. Every input has a default (random parents, an archive of them,
//    no latent space or a LinearModel for a mutator that needs one); MutatorCase overrides them.
//
// Helpers for your own tests: random_matrix, make_dataset, random_policies + rollout_all (traces
// of random policies), trace_difference; qd/testing/linear_model.hpp (a linear latent model) and
// qd/testing/elites.hpp (an archive given row by row).
//
// Build the test with the core's flags (CMake: qd_use_core_flags(<test target>), which
// qd_add_plugin() applies to plugins): Eigen objects cross between the test and libqd_core, and
// their alignment depends on -march. Every check first compares the test's build fingerprint with
// the core's and reports a mismatch instead of running.
//
// Header-only: it is compiled into the test that includes it. Uses std::thread (link Threads).
#pragma once

#include <qd/dataset.hpp>
#include <qd/descriptor.hpp>
#include <qd/environment.hpp>
#include <qd/errors.hpp>
#include <qd/mutator.hpp>
#include <qd/policy.hpp>
#include <qd/representation.hpp>
#include <qd/rng.hpp>
#include <qd/testing/elites.hpp>
#include <qd/testing/linear_model.hpp>
#include <qd/testing/policy_watch.hpp>
#include <qd/types.hpp>
#include <qd/version.hpp>

#include <Eigen/Core>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <ostream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace qd::testing {

// The outcome of a check: empty when the component conforms.
class Report {
 public:
  bool ok() const noexcept { return failures_.empty(); }
  const std::vector<std::string>& failures() const noexcept { return failures_; }
  void fail(std::string message) { failures_.push_back(std::move(message)); }
  // Records `message` unless `condition` holds; returns `condition`.
  bool expect(bool condition, const std::string& message) {
    if (!condition) fail(message);
    return condition;
  }
  std::string str() const {
    if (ok()) return "conforms";
    std::string s = std::to_string(failures_.size()) + " conformance failure(s):";
    for (const auto& f : failures_) s += "\n  - " + f;
    return s;
  }
  friend std::ostream& operator<<(std::ostream& out, const Report& r) { return out << r.str(); }

 private:
  std::vector<std::string> failures_;
};

// `rows` × `cols` entries drawn from U(-scale, scale), from a stream keyed by `seed`.
inline Matrix random_matrix(Eigen::Index rows, Eigen::Index cols, std::uint64_t seed, double scale = 1.0) {
  Matrix m(rows, cols);
  Rng rng(seed, Stream::kPlugin, 0x636f6e66 /* "conf" */, static_cast<std::uint64_t>(rows),
          static_cast<std::uint64_t>(cols));
  rng.fill_uniform(m.data(), static_cast<std::size_t>(m.size()), -scale, scale);
  return m;
}

// A dataset holding the rows of `params`, in cells 0, 1, ... (loop 0), as the core builds it.
inline Dataset make_dataset(const Matrix& params) {
  Dataset d(static_cast<std::size_t>(params.cols()));
  for (Eigen::Index i = 0; i < params.rows(); ++i) d.add(params.row(i).data(), i, 0);
  return d;
}

// A batch of policies for an environment: the network shape follows env.info() (observation and
// action sizes) and `hidden`, or is a plain vector of info().parameters values; parameters are
// U(-scale, scale); episode seeds differ per row.
struct PolicyBatch {
  PolicyShape shape;
  Matrix params;
  std::vector<std::uint64_t> episode_seeds;

  std::size_t size() const noexcept { return static_cast<std::size_t>(params.rows()); }
  RolloutBatch range(std::size_t begin, std::size_t end) const {
    return {&shape, params.data(), episode_seeds.data(), begin, end};
  }
};

inline PolicyBatch random_policies(const Environment& env, std::size_t n, const std::vector<int>& hidden = {8},
                                   double scale = 1.0, std::uint64_t seed = 1) {
  const EnvironmentInfo info = env.info();
  PolicyBatch b{info.parameters > 0 ? PolicyShape::direct(static_cast<std::size_t>(info.parameters))
                                    : PolicyShape(info.observation_size, hidden, info.action_size),
                Matrix(),
                {}};
  b.params = random_matrix(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(b.shape.param_count()), seed, scale);
  for (std::size_t i = 0; i < n; ++i) b.episode_seeds.push_back(Rng::derive_seed(seed, Stream::kEpisode, 0, 0, i));
  return b;
}

// Every policy of `policies` rolled out on the calling thread (traces start cleared, as the core
// hands them over).
inline std::vector<Trace> rollout_all(const Environment& env, const PolicyBatch& policies) {
  std::vector<Trace> traces(policies.size());
  env.rollout(policies.range(0, policies.size()), traces.data());
  return traces;
}

namespace detail {

inline bool same_build(Report& r) {
  if (std::strcmp(build_fingerprint(), QD_BUILD_FINGERPRINT) == 0) return true;
  r.fail(std::string("this test is compiled with other flags than libqd_core (build fingerprint '") +
         QD_BUILD_FINGERPRINT + "' here, '" + build_fingerprint() +
         "' in the core), so Eigen objects cannot safely cross between them and nothing was checked; "
         "compile the test with the core's flags (CMake: qd_use_core_flags(<target>))");
  return false;
}

// Runs f(), reporting an exception as a failure of `what`. Returns whether f() returned.
template <class F>
bool call(Report& r, const std::string& what, F&& f) {
  try {
    f();
    return true;
  } catch (const std::exception& e) {
    r.fail(what + " threw: " + e.what());
  } catch (...) {
    r.fail(what + " threw a non-standard exception");
  }
  return false;
}

// Runs f(t) for t = 0 .. count-1, each on its own thread. `in_turns` false: all at once (each
// thread starts f when all exist, so the calls overlap as much as they can); true: one after the
// other, thread t once thread t-1 has returned, every thread alive until the last has returned
// (so no two of them share a stack). Returns the first exception's message, or "".
template <class F>
std::string on_own_threads(std::size_t count, bool in_turns, const F& f) {
  std::vector<std::string> errors(count);
  std::vector<std::thread> threads;
  std::mutex mutex;
  std::condition_variable changed;
  std::size_t started = 0, turn = 0;
  for (std::size_t t = 0; t < count; ++t)
    threads.emplace_back([&, t] {
      std::unique_lock<std::mutex> lock(mutex);
      ++started;
      changed.notify_all();
      changed.wait(lock, [&] { return started == count && (!in_turns || turn == t); });
      lock.unlock();
      try {
        f(t);
      } catch (const std::exception& e) {
        errors[t] = e.what();
      } catch (...) {
        errors[t] = "a non-standard exception";
      }
      lock.lock();
      ++turn;
      changed.notify_all();
      changed.wait(lock, [&] { return turn == count; });
    });
  for (auto& t : threads) t.join();
  for (const auto& e : errors)
    if (!e.empty()) return e;
  return "";
}

template <class F>
std::string concurrently(std::size_t count, const F& f) {
  return on_own_threads(count, false, f);
}

// Splits [0, n) into `parts` contiguous ranges of unequal sizes (the k-th ends at n·k²/parts²)
// and runs f(begin, end) for each on its own thread, all at once (or in turns).
template <class F>
std::string on_threads(std::size_t n, int parts, const F& f, bool in_turns = false) {
  const auto count = static_cast<std::size_t>(std::max(parts, 1));
  return on_own_threads(count, in_turns, [&](std::size_t t) {
    const auto end_of = [&](std::size_t k) { return k == count ? n : n * k * k / (count * count); };
    f(end_of(t), end_of(t + 1));
  });
}

// The first few row indices where something broke, and how many in all.
class Rows {
 public:
  void add(std::size_t i, const std::string& what = "") {
    if (count_++ < 5) shown_ += (shown_.empty() ? "" : ", ") + std::to_string(i);
    if (detail_.empty()) detail_ = what;
  }
  bool empty() const noexcept { return count_ == 0; }
  // "rows 3, 7 (first: <detail>)".
  std::string str() const {
    std::string s = (count_ == 1 ? "row " : "rows ") + shown_;
    if (count_ > 5) s += " and " + std::to_string(count_ - 5) + " more";
    if (!detail_.empty()) s += " (first: " + detail_ + ")";
    return s;
  }
  // Records "<message>: <rows>" in `r` if any row was added.
  void report(Report& r, const std::string& message) const {
    if (!empty()) r.fail(message + ": " + str());
  }

 private:
  std::size_t count_ = 0;
  std::string shown_, detail_;
};

template <class Derived>
bool same_bits(const Eigen::PlainObjectBase<Derived>& a, const Eigen::PlainObjectBase<Derived>& b) {
  using Scalar = typename Derived::Scalar;
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         (a.size() == 0 || std::memcmp(a.data(), b.data(), static_cast<std::size_t>(a.size()) * sizeof(Scalar)) == 0);
}
template <class T>
bool same_bits(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}
inline bool same_bits(double a, double b) {
  return std::memcmp(&a, &b, sizeof(double)) == 0;
}

inline bool all_finite(const std::vector<double>& v) {
  return std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
}

inline std::string str(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

inline std::string shape(Eigen::Index rows, Eigen::Index cols) {
  return std::to_string(rows) + " x " + std::to_string(cols);
}

}  // namespace detail

// "" when two traces are identical (bit for bit), else their first difference ("steps 12 vs 13").
inline std::string trace_difference(const Trace& a, const Trace& b) {
  if (a.status != b.status) return std::string("status ") + to_string(a.status) + " vs " + to_string(b.status);
  if (a.steps != b.steps) return "steps " + std::to_string(a.steps) + " vs " + std::to_string(b.steps);
  if (!detail::same_bits(a.fitness, b.fitness))
    return "fitness " + detail::str(a.fitness) + " vs " + detail::str(b.fitness);
  if (a.main.cols != b.main.cols || !detail::same_bits(a.main.data, b.main.data)) return "main trajectory";
  if (a.aux.cols != b.aux.cols || !detail::same_bits(a.aux.data, b.aux.data)) return "aux trajectory";
  if (a.events != b.events) return "events";
  if (a.message != b.message) return "message '" + a.message + "' vs '" + b.message + "'";
  return "";
}

namespace detail {

// Compares traces row by row and reports the rows that differ.
inline void compare_traces(Report& r, const std::vector<Trace>& expected, const std::vector<Trace>& got,
                           std::size_t begin, std::size_t end, const std::string& message) {
  Rows rows;
  for (std::size_t i = begin; i < end; ++i) {
    const std::string d = trace_difference(expected[i], got[i]);
    if (!d.empty()) rows.add(i, d);
  }
  rows.report(r, message);
}

// What rollout() must not touch.
inline Trace sentinel_trace() {
  Trace t;
  t.status = EvalStatus::kFailed;
  t.steps = -7;
  t.fitness = -12345.5;
  t.main.reset(1);
  t.main.push(42.0);
  t.aux.reset(2);
  t.aux.push(1.0, 2.0);
  t.events = {99};
  t.message = "qd::testing sentinel: outside the rollout range";
  return t;
}

inline bool series_ok(const Series& s) {
  return s.cols >= 0 && (s.cols == 0 ? s.data.empty() : s.data.size() % static_cast<std::size_t>(s.cols) == 0);
}

// What save() writes.
template <class T>
std::string saved(const T& c) {
  std::ostringstream out;
  c.save(out);
  return out.str();
}

// load() of the first half of a saved state must throw qd::StateError (make() gives a fresh object).
template <class Make>
void expect_truncated_state_refused(Report& r, const std::string& blob, const Make& make) {
  if (blob.size() < 2) return;
  try {
    std::istringstream in(blob.substr(0, blob.size() / 2));
    make()->load(in);
    r.fail("load() of the first half of a saved state did not throw qd::StateError");
  } catch (const StateError&) {
  } catch (const std::exception& e) {
    r.fail(std::string("load() of the first half of a saved state threw another exception than qd::StateError: ") +
           e.what());
  }
}

}  // namespace detail

// ---- Environment ------------------------------------------------------------------------------

struct EnvironmentOptions {
  std::vector<int> hidden{8};  // hidden layers of the policies tried (inputs and outputs from info())
  std::size_t policies = 16;   // batch size (at least 4)
  double param_scale = 1.0;    // parameters ~ U(-scale, scale)
  int threads = 3;             // threads of the concurrent rollout
  std::uint64_t seed = 1;
  // The last policy of the batch gets NaN parameters, and its trace must not be kOk (a non-finite
  // action is an outcome, kInvalidAction). Turn off only for an environment that ignores actions.
  bool nan_policy_fails = true;
};

inline Report check_environment(const Environment& env, const EnvironmentOptions& o = {}) {
  Report r;
  if (!detail::same_build(r)) return r;
  EnvironmentInfo info;
  if (!detail::call(r, "info()", [&] { info = env.info(); })) return r;
  r.expect(info.parameters >= 0, "info().parameters = " + std::to_string(info.parameters));
  if (info.parameters == 0) {
    r.expect(info.observation_size > 0, "info().observation_size = " + std::to_string(info.observation_size));
    r.expect(info.action_size > 0, "info().action_size = " + std::to_string(info.action_size));
  }
  r.expect(info.max_steps > 0, "info().max_steps = " + std::to_string(info.max_steps));
  r.expect(!std::isinf(info.fitness_lower_bound), "info().fitness_lower_bound is infinite (NaN = not declared)");
  r.expect(info.has_fitness || std::isnan(info.fitness_lower_bound),
           "info() declares a fitness lower bound but has_fitness is false");
  if (!r.expect(o.policies >= 4, "EnvironmentOptions::policies must be at least 4") || !r.ok()) return r;

  const std::size_t n = o.policies;
  PolicyBatch batch = random_policies(env, n, o.hidden, o.param_scale, o.seed);
  if (o.nan_policy_fails) batch.params.row(static_cast<Eigen::Index>(n - 1)).setConstant(std::nan(""));
  auto run = [&](std::vector<Trace>& traces, std::size_t begin, std::size_t end) {
    env.rollout(batch.range(begin, end), traces.data());
  };

  std::vector<Trace> whole(n);
  if (!detail::call(r, "rollout() of the whole batch", [&] { run(whole, 0, n); })) return r;
  detail::Rows bad_status, no_message, bad_steps, bad_series, not_finite, below_bound;
  std::size_t ok_rows = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Trace& t = whole[i];
    if (static_cast<unsigned>(t.status) > static_cast<unsigned>(EvalStatus::kFailed))
      bad_status.add(i, std::to_string(static_cast<unsigned>(t.status)));
    else if (t.status != EvalStatus::kOk && t.message.empty())
      no_message.add(i, to_string(t.status));
    if (t.steps < 0 || t.steps > info.max_steps) bad_steps.add(i, std::to_string(t.steps));
    if (!detail::series_ok(t.main) || !detail::series_ok(t.aux)) bad_series.add(i);
    if (t.status == EvalStatus::kOk) {
      ok_rows += !(o.nan_policy_fails && i == n - 1);
      if (!std::isfinite(t.fitness) || !detail::all_finite(t.main.data) || !detail::all_finite(t.aux.data))
        not_finite.add(i);
      else if (info.has_fitness && t.fitness < info.fitness_lower_bound)
        below_bound.add(i, detail::str(t.fitness));
    }
  }
  below_bound.report(
      r, "kOk traces whose fitness is below info().fitness_lower_bound = " + detail::str(info.fitness_lower_bound));
  bad_status.report(r, "traces with a status that is not an EvalStatus value");
  no_message.report(r, "traces with status != kOk but no message saying why");
  bad_steps.report(r, "traces whose steps are outside [0, info().max_steps = " + std::to_string(info.max_steps) + "]");
  bad_series.report(r, "traces whose main or aux data is not a whole number of rows of `cols` values");
  not_finite.report(r, "kOk traces with a non-finite fitness or trajectory value");
  r.expect(ok_rows > 0, "no rollout of " + std::to_string(n) + " random policies ended with status kOk");
  if (o.nan_policy_fails)
    r.expect(whole[n - 1].status != EvalStatus::kOk,
             "a policy with NaN parameters ended with status kOk (a non-finite action must give kInvalidAction)");

  std::vector<Trace> again(n);
  if (detail::call(r, "a second rollout() of the whole batch", [&] { run(again, 0, n); }))
    detail::compare_traces(r, whole, again, 0, n, "a second rollout of the same policies and episode seeds differs");

  std::vector<Trace> threaded(n);
  const std::string error =
      detail::on_threads(n, o.threads, [&](std::size_t b, std::size_t e) { run(threaded, b, e); });
  if (r.expect(error.empty(), "rollout() on several threads threw: " + error))
    detail::compare_traces(
        r, whole, threaded, 0, n,
        "rollouts on " + std::to_string(o.threads) + " threads over disjoint ranges differ from one thread's");

  // Shared state between calls gives wrong traces only when calls overlap, which the scheduler
  // decides. A shared qd::Policy is found whatever it decides: the threads take turns (one call
  // each, all threads alive) while the core watches which threads load each Policy object.
  std::vector<Trace> in_turns(n);
  watch_policy_loads(true);
  const std::string turn_error = detail::on_threads(
      n, std::max(o.threads, 2), [&](std::size_t b, std::size_t e) { run(in_turns, b, e); }, true);
  watch_policy_loads(false);
  if (r.expect(turn_error.empty(), "rollout() on several threads in turn threw: " + turn_error)) {
    r.expect(!policy_loaded_on_two_threads(),
             "rollout() loads one qd::Policy object on several threads (a Policy kept between calls, such as a "
             "mutable member): a Policy is not thread-safe and concurrent rollouts would overwrite each other's "
             "parameters; make one per rollout() call");
    detail::compare_traces(r, whole, in_turns, 0, n,
                           "rollouts on several threads in turn over disjoint ranges differ from one thread's");
  }

  // A range touches its own rows only (and starts from empty traces, as the core hands them over).
  const std::size_t begin = n / 4, end = begin + n / 2;
  const std::string range = "[" + std::to_string(begin) + ", " + std::to_string(end) + ")";
  std::vector<Trace> part(n, detail::sentinel_trace());
  if (detail::call(r, "rollout() of the empty range [" + std::to_string(begin) + ", " + std::to_string(begin) + ")",
                   [&] { run(part, begin, begin); }))
    detail::compare_traces(r, std::vector<Trace>(n, detail::sentinel_trace()), part, 0, n,
                           "rollout() of an empty range wrote traces");
  for (std::size_t i = begin; i < end; ++i) part[i] = Trace();
  if (detail::call(r, "rollout() of rows " + range, [&] { run(part, begin, end); })) {
    const std::vector<Trace> sentinels(n, detail::sentinel_trace());
    detail::compare_traces(r, sentinels, part, 0, begin, "rollout() of rows " + range + " wrote outside its range");
    detail::compare_traces(r, sentinels, part, end, n, "rollout() of rows " + range + " wrote outside its range");
    detail::compare_traces(r, whole, part, begin, end,
                           "rollout() of rows " + range + " differs from the same rows of the whole batch");
  }
  return r;
}

// ---- Descriptor -------------------------------------------------------------------------------

struct DescriptorOptions {
  int threads = 3;
  // At least one of the traces must get a cell (>= 0).
  bool require_described = true;
};

// `traces`: rollouts of your environment (rollout_all(env, random_policies(env, 32))) or traces
// made by hand; those whose status is not kOk are left out, as the core does.
inline Report check_descriptor(const Descriptor& d, const std::vector<Trace>& traces, const DescriptorOptions& o = {}) {
  Report r;
  if (!detail::same_build(r)) return r;
  GridSpec g, again;
  if (!detail::call(r, "grid()", [&] {
        g = d.grid();
        again = d.grid();
      }))
    return r;
  const std::size_t dims = g.dims();
  r.expect(dims > 0 && !g.shape.empty(), "grid() has no dimensions (names or shape empty)");
  r.expect(g.lower.size() == dims && g.upper.size() == dims, "grid() has " + std::to_string(dims) + " names but " +
                                                                 std::to_string(g.lower.size()) + " lower and " +
                                                                 std::to_string(g.upper.size()) + " upper bounds");
  r.expect(g.cells > 0, "grid().cells = " + std::to_string(g.cells));
  for (std::size_t k = 0; k < std::min({dims, g.lower.size(), g.upper.size()}); ++k)
    r.expect(std::isfinite(g.lower[k]) && std::isfinite(g.upper[k]) && g.lower[k] < g.upper[k],
             "grid() range of dimension " + std::to_string(k) + " is [" + detail::str(g.lower[k]) + ", " +
                 detail::str(g.upper[k]) + "]");
  if (g.is_cvt()) {
    r.expect(g.shape.size() == 1 && g.shape[0] == g.cells, "a CVT grid()'s shape is not [cells]");
    r.expect(g.centroids.size() == static_cast<std::size_t>(g.cells) * dims,
             "grid() has " + std::to_string(g.centroids.size()) + " centroid values for " + std::to_string(g.cells) +
                 " cells of " + std::to_string(dims) + " dimensions");
    r.expect(detail::all_finite(g.centroids), "grid() has non-finite centroids");
  } else {
    r.expect(g.shape.size() == dims, "grid() has " + std::to_string(g.shape.size()) + " shape dimensions but " +
                                         std::to_string(dims) + " names");
    std::int64_t product = 1;
    for (std::size_t k = 0; k < g.shape.size(); ++k) {
      r.expect(g.shape[k] > 0, "grid().shape[" + std::to_string(k) + "] = " + std::to_string(g.shape[k]));
      product *= g.shape[k];
    }
    r.expect(g.cells == product, "grid().cells = " + std::to_string(g.cells) + " but the product of grid().shape is " +
                                     std::to_string(product) +
                                     " (cells are row-major over the shape; the core refuses such a grid)");
  }
  r.expect(g.labels.empty() || (!g.is_cvt() && g.labels.size() == dims),
           "grid() has bin labels for " + std::to_string(g.labels.size()) + " of its " + std::to_string(dims) +
               " dimensions (give one list per dimension, empty where the bins are numbered; a CVT has none)");
  for (std::size_t k = 0; k < g.labels.size() && k < g.shape.size(); ++k)
    r.expect(g.labels[k].empty() || static_cast<std::int64_t>(g.labels[k].size()) == g.shape[k],
             "grid() has " + std::to_string(g.labels[k].size()) + " bin labels for dimension " + std::to_string(k) +
                 " of " + std::to_string(g.shape[k]) + " bins");
  r.expect(again.shape == g.shape && again.names == g.names && again.cells == g.cells && again.labels == g.labels &&
               detail::same_bits(again.lower, g.lower) && detail::same_bits(again.upper, g.upper) &&
               detail::same_bits(again.centroids, g.centroids),
           "grid() changed between two calls");
  if (!r.ok()) return r;

  std::vector<Trace> in;
  for (const Trace& t : traces)
    if (t.status == EvalStatus::kOk) in.push_back(t);
  const std::size_t n = in.size();
  if (!r.expect(n > 0, "no trace with status kOk to describe")) return r;
  auto describe = [&](std::vector<std::int64_t>& cells, std::vector<double>& values, std::size_t b, std::size_t e) {
    d.describe(in.data() + b, e - b, cells.data() + b, values.data() + b * dims);
  };
  // Cells start at -2 (never valid) and values at NaN, so unwritten results show.
  std::vector<std::int64_t> cells(n, -2), cells2(cells), cells3(cells);
  std::vector<double> values(n * dims, std::nan("")), values2(values), values3(values);
  if (!detail::call(r, "describe() of " + std::to_string(n) + " traces", [&] {
        d.describe(in.data(), 0, cells.data(), values.data());
        describe(cells, values, 0, n);
      }))
    return r;
  detail::Rows bad_cell, bad_values;
  std::size_t described = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (cells[i] < -1 || cells[i] >= g.cells) bad_cell.add(i, "cell " + std::to_string(cells[i]));
    if (cells[i] < 0) continue;
    ++described;
    for (std::size_t k = 0; k < dims; ++k)
      if (!std::isfinite(values[i * dims + k])) bad_values.add(i, "value " + std::to_string(k));
  }
  bad_cell.report(r, "cells outside [0, grid().cells = " + std::to_string(g.cells) + ") and not -1");
  bad_values.report(r, "described traces with a value that is non-finite or not written");
  if (o.require_described)
    r.expect(described > 0, "none of " + std::to_string(n) + " kOk traces was described (all cells -1)");

  // Results repeat, and do not depend on threads or on how the traces are split.
  auto compare = [&](const std::vector<std::int64_t>& c, const std::vector<double>& v, const std::string& message) {
    detail::Rows rows;
    for (std::size_t i = 0; i < n; ++i) {
      if (c[i] != cells[i])
        rows.add(i, "cell " + std::to_string(cells[i]) + " vs " + std::to_string(c[i]));
      else if (cells[i] >= 0 && std::memcmp(&v[i * dims], &values[i * dims], dims * sizeof(double)) != 0)
        rows.add(i, "values");
    }
    rows.report(r, message);
  };
  if (detail::call(r, "a second describe()", [&] { describe(cells2, values2, 0, n); }))
    compare(cells2, values2, "a second describe() of the same traces differs");
  const std::string error =
      detail::on_threads(n, o.threads, [&](std::size_t b, std::size_t e) { describe(cells3, values3, b, e); });
  if (r.expect(error.empty(), "describe() on several threads threw: " + error))
    compare(cells3, values3,
            "describe() on " + std::to_string(o.threads) + " threads over parts of the traces differs from one call");
  return r;
}

// ---- Representation ---------------------------------------------------------------------------

using RepresentationFactory = std::function<std::unique_ptr<Representation>()>;

struct RepresentationOptions {
  FitContext fit{0, 1};  // passed to fit()
  std::size_t rows = 8;  // the first `rows` rows of the dataset are encoded, decoded, ...
  int threads = 3;       // concurrent callers of the const members
  // Central differences of decode: step fd_step·max(1, |z_k|). The tolerances are relative:
  // ‖J − J_fd‖ ≤ jacobian_tolerance·‖J_fd‖ (Frobenius, per row), ‖vjp − vᵀJ‖ ≤ vjp_tolerance·‖vᵀJ‖,
  // |e − ‖θ − Dec(Enc(θ))‖| ≤ reconstruction_tolerance·max(1, ‖θ‖). The defaults suit models that
  // compute in double; a float32 model wants about fd_step = 1e-2, jacobian_tolerance = 1e-2 and
  // 1e-5 for the other two.
  double fd_step = 1e-6;
  double jacobian_tolerance = 1e-5;
  double vjp_tolerance = 1e-10;
  double reconstruction_tolerance = 1e-10;
  // Two fresh models fitted on the same dataset with the same context save identical states.
  bool check_fit_determinism = true;
};

namespace detail {

// Everything the const members of a representation compute for one input.
struct RepresentationOutputs {
  Matrix z, decoded, vjp;
  std::vector<Matrix> jacobians;
  Vector errors;
};

inline RepresentationOutputs compute(const Representation& rep, const Matrix& theta, const Matrix& v) {
  RepresentationOutputs out;
  rep.encode(theta, out.z);
  rep.decode(out.z, out.decoded);
  rep.decoder_jacobians(out.z, out.jacobians);
  rep.decoder_vjp(out.z, v, out.vjp);
  rep.reconstruction_errors(theta, out.errors);
  return out;
}

// "" when identical, else the first member that differs.
inline std::string difference(const RepresentationOutputs& a, const RepresentationOutputs& b) {
  if (!same_bits(a.z, b.z)) return "encode";
  if (!same_bits(a.decoded, b.decoded)) return "decode";
  if (a.jacobians.size() != b.jacobians.size()) return "decoder_jacobians";
  for (std::size_t i = 0; i < a.jacobians.size(); ++i)
    if (!same_bits(a.jacobians[i], b.jacobians[i])) return "decoder_jacobians";
  if (!same_bits(a.vjp, b.vjp)) return "decoder_vjp";
  if (!same_bits(a.errors, b.errors)) return "reconstruction_errors";
  return "";
}

}  // namespace detail

// `make` returns a fresh, unfitted model (the factory's result for your configuration); `data`
// is what it is fitted on (make_dataset(random_matrix(...)) or your own).
inline Report check_representation(const RepresentationFactory& make, const Dataset& data,
                                   const RepresentationOptions& o = {}) {
  Report r;
  if (!detail::same_build(r)) return r;
  std::unique_ptr<Representation> a, b;
  FitReport fit;
  if (!detail::call(r, "making and fitting the model", [&] {
        a = make();
        b = make();
        fit = a->fit(data, o.fit);
      }))
    return r;
  if (!r.expect(a && b, "the factory returned null")) return r;
  r.expect(fit.epochs >= 0 && !std::isinf(fit.train_loss) && !std::isinf(fit.test_loss),
           "fit() reported " + std::to_string(fit.epochs) + " epochs, train loss " + detail::str(fit.train_loss) +
               ", test loss " + detail::str(fit.test_loss));
  const int ld = a->latent_size();
  if (!r.expect(ld >= 0, "latent_size() = " + std::to_string(ld))) return r;

  std::string blob;
  if (!detail::call(r, "save()", [&] { blob = detail::saved(*a); })) return r;
  if (o.check_fit_determinism && detail::call(r, "fitting a second model", [&] { b->fit(data, o.fit); }))
    r.expect(detail::saved(*b) == blob,
             "two fresh models fitted on the same dataset and context save different states");
  std::unique_ptr<Representation> loaded;
  const bool loaded_ok = detail::call(r, "load() of a saved state into a fresh model", [&] {
    loaded = make();
    std::istringstream in(blob);
    loaded->load(in);
  });
  if (loaded_ok)
    r.expect(detail::saved(*loaded) == blob, "save() after load() gives another state than the one loaded");
  detail::expect_truncated_state_refused(r, blob, make);
  if (ld == 0 || !r.ok()) return r;  // no latent space: encode, decode, ... must not be called

  const auto p = static_cast<Eigen::Index>(data.param_count());
  const auto n = static_cast<Eigen::Index>(std::min(o.rows, data.size()));
  if (!r.expect(n > 0, "the dataset is empty")) return r;
  const Matrix theta = data.params().topRows(n);
  const Matrix v = random_matrix(n, p, 7);
  detail::RepresentationOutputs out;
  if (!detail::call(r, "encode/decode/decoder_jacobians/decoder_vjp/reconstruction_errors",
                    [&] { out = detail::compute(*a, theta, v); }))
    return r;
  const std::string sizes =
      " (N = " + std::to_string(n) + ", P = " + std::to_string(p) + ", LD = " + std::to_string(ld) + ")";
  r.expect(out.z.rows() == n && out.z.cols() == ld,
           "encode() gave " + detail::shape(out.z.rows(), out.z.cols()) + ", not N x LD" + sizes);
  r.expect(out.decoded.rows() == n && out.decoded.cols() == p,
           "decode() gave " + detail::shape(out.decoded.rows(), out.decoded.cols()) + ", not N x P" + sizes);
  r.expect(out.vjp.rows() == n && out.vjp.cols() == ld,
           "decoder_vjp() gave " + detail::shape(out.vjp.rows(), out.vjp.cols()) + ", not N x LD" + sizes);
  r.expect(out.errors.size() == n,
           "reconstruction_errors() gave " + std::to_string(out.errors.size()) + " values" + sizes);
  bool jacobian_shapes = out.jacobians.size() == static_cast<std::size_t>(n);
  for (const Matrix& j : out.jacobians) jacobian_shapes = jacobian_shapes && j.rows() == p && j.cols() == ld;
  r.expect(jacobian_shapes, "decoder_jacobians() did not give N matrices of P x LD" + sizes);
  if (!r.ok()) return r;
  r.expect(out.z.allFinite(), "encode() gave non-finite values");
  r.expect(out.decoded.allFinite(), "decode() gave non-finite values");
  r.expect(out.errors.allFinite(), "reconstruction_errors() gave non-finite values");

  // Jacobians against central differences of decode (all 2·LD points of a row in one call).
  detail::Rows jacobian_rows, vjp_rows, error_rows;
  for (Eigen::Index i = 0; i < n; ++i) {
    const Matrix& j = out.jacobians[static_cast<std::size_t>(i)];
    Matrix points = out.z.row(i).replicate(2 * ld, 1), decoded;
    for (Eigen::Index k = 0; k < ld; ++k) {
      const double h = o.fd_step * std::max(1.0, std::abs(out.z(i, k)));
      points(2 * k, k) += h;
      points(2 * k + 1, k) -= h;
    }
    if (!detail::call(r, "decode() of perturbed latent points", [&] { a->decode(points, decoded); })) return r;
    Matrix fd(p, ld);
    for (Eigen::Index k = 0; k < ld; ++k)
      fd.col(k) = (decoded.row(2 * k) - decoded.row(2 * k + 1)).transpose() / (points(2 * k, k) - points(2 * k + 1, k));
    const double err = (j - fd).norm(), scale = fd.norm();
    if (!(err <= o.jacobian_tolerance * std::max(scale, 1e-12)))
      jacobian_rows.add(static_cast<std::size_t>(i), "relative error " + detail::str(err / scale));
    const RowVector expected = v.row(i) * j;
    const double verr = (out.vjp.row(i) - expected).norm();
    if (!(verr <= o.vjp_tolerance * std::max(expected.norm(), 1e-12)))
      vjp_rows.add(static_cast<std::size_t>(i), "relative error " + detail::str(verr / expected.norm()));
    const double recn = (theta.row(i) - out.decoded.row(i)).norm();
    if (!(std::abs(out.errors(i) - recn) <= o.reconstruction_tolerance * std::max(1.0, theta.row(i).norm())))
      error_rows.add(static_cast<std::size_t>(i), detail::str(out.errors(i)) + " vs " + detail::str(recn));
  }
  jacobian_rows.report(r, "decoder_jacobians() differ from central differences of decode()");
  vjp_rows.report(r, "decoder_vjp() differs from v J (J from decoder_jacobians())");
  error_rows.report(r, "reconstruction_errors() differ from |theta - decode(encode(theta))|");

  // The loaded model computes exactly what the saved one does.
  if (loaded_ok) {
    detail::RepresentationOutputs again;
    if (detail::call(r, "the loaded model", [&] { again = detail::compute(*loaded, theta, v); })) {
      const std::string d = detail::difference(out, again);
      r.expect(d.empty(), d + "() of the loaded model differs from the saved one's");
    }
  }

  // The const members run concurrently (the core calls them from several threads).
  std::vector<detail::RepresentationOutputs> concurrent(static_cast<std::size_t>(std::max(o.threads, 1)));
  const std::string error =
      detail::concurrently(concurrent.size(), [&](std::size_t t) { concurrent[t] = detail::compute(*a, theta, v); });
  if (r.expect(error.empty(), "const members on several threads threw: " + error))
    for (const auto& c : concurrent) {
      const std::string d = detail::difference(out, c);
      if (!r.expect(d.empty(), d + "() called from several threads at once differs from one thread's")) break;
    }
  return r;
}

// ---- Mutator ----------------------------------------------------------------------------------

using MutatorFactory = std::function<std::unique_ptr<Mutator>()>;

// What the mutator is given. Every field has a default, so check_mutator(make) alone runs.
struct MutatorCase {
  // The selected parents, one row per offspring (the core selects `count` of them). Empty: `count`
  // rows of `params` values drawn from U(-1, 1). Mutators whose uses_parents() is false get none.
  Parents parents;
  std::size_t count = 16;
  std::size_t params = 12;
  // The representation (not owned). Null: none with a latent space, or, for a mutator whose
  // needs_latent() is true, a LinearModel::random() with min(3, params - 1) latent dimensions.
  const Representation* representation = nullptr;
  // The archive (not owned). Null: the parents as elites, parent i in cell i.
  const ArchiveView* archive = nullptr;
  // The dataset begin_loop() sees (not owned). Null: the parents' parameters.
  const Dataset* dataset = nullptr;
  int loop = 1;
  int iterations = 3;  // rounds of mutate() and feedback() per loop
  std::uint64_t seed = 1;
};

namespace detail {

// The representation of a run without a latent model: latent_size() 0, and the rest must not be
// called (they throw, which check_mutator reports).
class NoLatentSpace final : public Representation {
 public:
  int latent_size() const noexcept override { return 0; }
  FitReport fit(const Dataset&, const FitContext&) override { return {}; }
  void encode(const Matrix&, Matrix&) const override { misuse("encode"); }
  void decode(const Matrix&, Matrix&) const override { misuse("decode"); }
  void decoder_jacobians(const Matrix&, std::vector<Matrix>&) const override { misuse("decoder_jacobians"); }
  void save(std::ostream&) const override {}
  void load(std::istream&) override {}

 private:
  [[noreturn]] static void misuse(const char* what) {
    throw std::logic_error(std::string(what) + "() called on a representation whose latent_size() is 0");
  }
};

// "" when two batches of offspring are identical, else the first member that differs. Latent rows
// count only where has_latent is set (the others are whatever Offspring::reset left).
inline std::string difference(const Offspring& a, const Offspring& b) {
  if (!same_bits(a.theta, b.theta)) return "theta";
  if (a.has_latent != b.has_latent) return "has_latent";
  for (std::size_t i = 0; i < a.has_latent.size(); ++i) {
    const auto row = static_cast<Eigen::Index>(i);
    if (a.has_latent[i] && (a.latent.cols() != b.latent.cols() || row >= a.latent.rows() || row >= b.latent.rows() ||
                            !same_bits(RowVector(a.latent.row(row)), RowVector(b.latent.row(row)))))
      return "latent";
  }
  if (!same_bits(a.metrics, b.metrics)) return "metrics";
  return "";
}

// The contract of one batch of offspring.
inline void check_offspring(Report& r, const Offspring& out, std::size_t count, Eigen::Index p, int ld,
                            const std::vector<std::string>& names, const std::string& where) {
  const std::size_t metrics = names.size();
  const auto n = static_cast<Eigen::Index>(count);
  if (!r.expect(out.theta.rows() == n && out.theta.cols() == p,
                where + "theta is " + shape(out.theta.rows(), out.theta.cols()) + ", not count x P = " + shape(n, p)))
    return;
  r.expect(out.theta.allFinite(), where + "theta has non-finite values (from finite parents)");
  r.expect(out.has_latent.size() == count, where + "has_latent has " + std::to_string(out.has_latent.size()) +
                                               " entries, not count = " + std::to_string(count));
  Rows bad_flag, bad_latent;
  for (std::size_t i = 0; i < std::min(count, out.has_latent.size()); ++i) {
    if (out.has_latent[i] > 1) bad_flag.add(i, std::to_string(out.has_latent[i]));
    if (out.has_latent[i] == 0) continue;
    const auto row = static_cast<Eigen::Index>(i);
    if (ld == 0 || out.latent.rows() <= row || out.latent.cols() != ld || !out.latent.row(row).allFinite())
      bad_latent.add(i);
  }
  bad_flag.report(r, where + "has_latent entries other than 0 and 1");
  bad_latent.report(
      r, where + "offspring marked has_latent without a finite latent row of LD = " + std::to_string(ld) + " values");
  r.expect(out.metrics.size() == metrics,
           where + std::to_string(out.metrics.size()) + " metrics for " + std::to_string(metrics) + " metric_names()");
  r.expect(all_finite(out.metrics), where + "non-finite metrics");
  for (std::size_t k = 0; k < std::min(metrics, out.metrics.size()); ++k)
    if (names[k] == kMixingRatio)
      r.expect(out.metrics[k] >= 0.0 && out.metrics[k] <= 1.0,
               where + "mixing ratio " + str(out.metrics[k]) + " is not in [0, 1]");
}

}  // namespace detail

// `make` returns a fresh mutator (the factory's result for your configuration). Runs two of them
// side by side through begin_loop, `iterations` × (mutate, feedback) with scripted outcomes, then
// saves one, loads the state into a third, and runs the next loop's begin_loop and mutate on both.
inline Report check_mutator(const MutatorFactory& make, MutatorCase c = {}) {
  Report r;
  if (!detail::same_build(r)) return r;
  std::unique_ptr<Mutator> a, b;
  if (!detail::call(r, "making the mutator", [&] {
        a = make();
        b = make();
      }))
    return r;
  if (!r.expect(a && b, "the factory returned null")) return r;
  const bool uses_parents = a->uses_parents(), needs_latent = a->needs_latent();
  std::vector<std::string> names;
  if (!detail::call(r, "metric_names()", [&] { names = a->metric_names(); })) return r;

  // The case's defaults.
  if (c.parents.theta.size() == 0)
    c.parents.theta = random_matrix(static_cast<Eigen::Index>(c.count), static_cast<Eigen::Index>(c.params), c.seed);
  c.count = static_cast<std::size_t>(c.parents.theta.rows());
  const Eigen::Index p = c.parents.theta.cols();
  if (!r.expect(c.count > 0 && p > 0, "MutatorCase: no parents")) return r;
  std::unique_ptr<Representation> own_representation;
  if (!c.representation) {
    if (needs_latent)
      own_representation = LinearModel::random(
          static_cast<int>(std::min<Eigen::Index>(3, std::max<Eigen::Index>(p - 1, 1))), static_cast<int>(p), c.seed);
    else
      own_representation = std::make_unique<detail::NoLatentSpace>();
    c.representation = own_representation.get();
  }
  const int ld = c.representation->latent_size();
  if (!r.expect(!needs_latent || ld > 0,
                "MutatorCase: needs_latent() is true but the representation has no latent space"))
    return r;
  if (c.parents.recn_error.size() == 0) {
    c.parents.recn_error = Vector::Zero(c.parents.theta.rows());
    if (ld > 0 && !detail::call(r, "reconstruction_errors() of the case's representation", [&] {
          c.representation->reconstruction_errors(c.parents.theta, c.parents.recn_error);
        }))
      return r;
  }
  if (c.parents.cells.empty())
    for (std::size_t i = 0; i < c.count; ++i) c.parents.cells.push_back(static_cast<std::int64_t>(i));
  std::unique_ptr<Elites> own_archive;
  if (!c.archive) {
    own_archive = std::make_unique<Elites>(static_cast<std::int64_t>(2 * c.count), static_cast<std::size_t>(p), 1);
    for (std::size_t i = 0; i < c.count; ++i) {
      const auto row = static_cast<Eigen::Index>(i);
      own_archive->add(static_cast<std::int64_t>(i),
                       std::vector<double>(c.parents.theta.row(row).data(), c.parents.theta.row(row).data() + p),
                       c.parents.recn_error(row));
    }
    c.archive = own_archive.get();
  }
  std::unique_ptr<Dataset> own_dataset;
  if (!c.dataset) {
    own_dataset = std::make_unique<Dataset>(make_dataset(c.parents.theta));
    c.dataset = own_dataset.get();
  }

  // Iteration `it` of `loop` on mutator m, as the core runs it.
  const Parents none;
  auto mutate = [&](Mutator& m, int loop, int it, Offspring& out) {
    Rng rng(c.seed, Stream::kMutation, static_cast<std::uint64_t>(loop), static_cast<std::uint64_t>(it));
    MutateContext ctx;
    ctx.loop = loop;
    ctx.iteration = it;
    ctx.rng = &rng;
    ctx.representation = c.representation;
    ctx.archive = c.archive;
    out.reset(c.count, static_cast<std::size_t>(p), static_cast<std::size_t>(ld));
    m.mutate(uses_parents ? c.parents : none, c.count, ctx, out);
  };
  const LoopContext loop_context{c.loop, c.archive, c.dataset, c.representation};
  if (!detail::call(r, "begin_loop()", [&] {
        a->begin_loop(loop_context);
        b->begin_loop(loop_context);
      }))
    return r;
  // Scripted outcomes, cycling through new cell, improved, replaced and discarded, with fitnesses.
  std::vector<OffspringResult> results(c.count);
  for (std::size_t i = 0; i < c.count; ++i) {
    OffspringResult& x = results[i];
    x.outcome = static_cast<Outcome>(i % 4);
    x.cell = static_cast<std::int64_t>(i);
    x.fitness = 1.0 + 0.25 * static_cast<double>(i % 7);
    if (x.outcome != Outcome::kNewCell)
      x.previous = x.outcome == Outcome::kImproved ? x.fitness - 0.5 : x.fitness + 0.5;
  }
  for (int it = 0; it < c.iterations; ++it) {
    const std::string where = "loop " + std::to_string(c.loop) + " iteration " + std::to_string(it) + ": ";
    Offspring out_a, out_b;
    if (!detail::call(r, where + "mutate()", [&] {
          mutate(*a, c.loop, it, out_a);
          mutate(*b, c.loop, it, out_b);
        }))
      return r;
    detail::check_offspring(r, out_a, c.count, p, ld, names, where);
    const std::string d = detail::difference(out_a, out_b);
    r.expect(d.empty(), where + "two fresh mutators given the same inputs and Rng seed differ in " + d);
    Feedback fb;
    fb.loop = c.loop;
    fb.iteration = it;
    fb.offspring = c.count;
    fb.added = (c.count + 3) / 4;
    fb.replaced = (c.count + 2) / 4 + (c.count + 1) / 4;
    fb.rejected = c.count / 4;
    fb.results = &results;
    if (!detail::call(r, where + "feedback()", [&] {
          a->feedback(fb);
          b->feedback(fb);
        }))
      return r;
    if (!r.ok()) return r;
  }

  // A checkpoint at the loop boundary: the loaded mutator goes on exactly as the saved one.
  std::string blob;
  std::unique_ptr<Mutator> loaded;
  if (!detail::call(r, "save() and load() into a fresh mutator", [&] {
        blob = detail::saved(*a);
        loaded = make();
        std::istringstream in(blob);
        loaded->load(in);
      }))
    return r;
  r.expect(detail::saved(*loaded) == blob, "save() after load() gives another state than the one loaded");
  const LoopContext next{c.loop + 1, c.archive, c.dataset, c.representation};
  Offspring out_a, out_loaded;
  if (detail::call(r, "begin_loop() and mutate() after load()", [&] {
        a->begin_loop(next);
        loaded->begin_loop(next);
        mutate(*a, c.loop + 1, 0, out_a);
        mutate(*loaded, c.loop + 1, 0, out_loaded);
      })) {
    const std::string d = detail::difference(out_a, out_loaded);
    r.expect(d.empty(), "after save() and load(), the loaded mutator's next offspring differ in " + d);
  }
  detail::expect_truncated_state_refused(r, blob, make);
  return r;
}

}  // namespace qd::testing
