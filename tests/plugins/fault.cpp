// Fault injection (issue 20): components that misbehave on purpose at one chosen place in a run, so
// tests can check that qdrun reports every kind of plugin fault (tests/e2e/plugin_faults.sh).
//
//  * environment "fault-arm": a small planar arm (like environments/arm) whose rollout of one
//    offspring, chosen by (fault_loop, fault_iteration, fault_offspring), does `fault`: segfault,
//    abort, exit0, exit1, throw, hang, nan-fitness; or marks its trace so that the descriptor
//    "fault-endpoint" returns an inf or NaN descriptor value or a cell outside the grid
//    (inf-descriptor, nan-descriptor, cell-out-of-range). The offspring is recognised by its
//    episode seed, which the core derives from (run seed, loop, iteration, offspring), so the
//    fault lands on the same offspring whatever the backend or worker count.
//  * mutator "fault-mutator": a uniform sampler that, at (fault_loop, fault_iteration), returns
//    one row too few (short), a NaN parameter (nan), throws (throw), crashes (segfault) or calls
//    exit(0) (exit0) or quick_exit(0) (quick-exit): mutators run in qdrun's own process under every
//    backend.
//  * representation "fault-linear": latent code = the first `latent` parameters; from loop
//    fault_loop (>= 2) on its decode() returns NaN (nan-decode) or encode() one row too few
//    (short-encode).
//
// The environment variable QD_FAULT_DISABLE=1 switches every fault off without changing the
// configuration: the stand-in for an author fixing the plugin before qdrun --resume.
#include <qd/plugin.hpp>
#include <qd/rng.hpp>

#include <unistd.h>
#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <istream>
#include <limits>
#include <ostream>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

bool faults_enabled() {
  const char* off = std::getenv("QD_FAULT_DISABLE");
  return !(off && std::string(off) == "1");
}

constexpr int kMarkerInf = -1001, kMarkerNan = -1002, kMarkerCell = -1003;  // trace events for the descriptor
constexpr int kJoints = 3;

constexpr qd::ParamSpec kEnvParams[] = {
    qd::param_int("steps", "50", 1, 1000000, "steps per episode"),
    qd::param_string("fault", "\"none\"",
                     "none|segfault|abort|exit0|exit1|throw|hang|nan-fitness|inf-descriptor|nan-descriptor|"
                     "cell-out-of-range",
                     "what the chosen rollout does"),
    qd::param_int("fault_loop", "1", 0, 1e9, "loop of the faulty offspring"),
    qd::param_int("fault_iteration", "0", 0, 1e9, "iteration of the faulty offspring (0 in loop 0)"),
    qd::param_int("fault_offspring", "0", 0, 1e9, "index of the faulty offspring in its batch"),
    qd::param_int("fault_count", "1", 1, 1e9,
                  "offspring fault_offspring to fault_offspring + fault_count - 1 fault (several at once on the "
                  "threads backend)"),
};

class FaultArm final : public qd::Environment {
 public:
  FaultArm(const qd::Config& c, const qd::BuildContext& b)
      : steps_(static_cast<int>(c.get_int("steps"))), fault_(faults_enabled() ? c.get_string("fault") : "none") {
    for (std::int64_t k = 0; k < c.get_int("fault_count"); ++k)
      targets_.push_back(qd::Rng::derive_seed(b.seed, qd::Stream::kEpisode,
                                              static_cast<std::uint64_t>(c.get_int("fault_loop")),
                                              static_cast<std::uint64_t>(c.get_int("fault_iteration")),
                                              static_cast<std::uint64_t>(c.get_int("fault_offspring") + k)));
  }

  qd::EnvironmentInfo info() const override { return {kJoints + 2, kJoints, steps_}; }

  void rollout(const qd::RolloutBatch& batch, qd::Trace* traces) const override {
    qd::Policy policy(*batch.shape);
    std::vector<float> obs(kJoints + 2);
    for (std::size_t i = batch.begin; i < batch.end; ++i) {
      qd::Trace& t = traces[i];
      t.main.reset(2);
      policy.load(batch.row(i));
      double angles[kJoints] = {0, 0, 0}, x = 1, y = 0, energy = 0;
      for (int step = 0; step < steps_; ++step) {
        for (int j = 0; j < kJoints; ++j) obs[static_cast<std::size_t>(j)] = static_cast<float>(angles[j]);
        obs[kJoints] = static_cast<float>(x);
        obs[kJoints + 1] = static_cast<float>(y);
        const float* a = policy.act(obs.data());
        double phi = 0;
        x = y = 0;
        for (int j = 0; j < kJoints; ++j) {
          const double v = std::isfinite(a[j]) ? std::clamp(static_cast<double>(a[j]), -1.0, 1.0) : 0.0;
          angles[j] += 0.1 * v;
          energy += v * v;
          phi += angles[j];
          x += std::cos(phi) / kJoints;
          y += std::sin(phi) / kJoints;
        }
        t.steps = step + 1;
      }
      t.main.push(x, y);
      t.fitness = -0.1 * energy;
      if (fault_ != "none" && std::find(targets_.begin(), targets_.end(), batch.episode_seeds[i]) != targets_.end())
        inject(t);
    }
  }

 private:
  void inject(qd::Trace& t) const {
    if (fault_ == "segfault") std::raise(SIGSEGV);
    if (fault_ == "abort") std::abort();
    if (fault_ == "exit0") std::exit(0);
    if (fault_ == "exit1") std::exit(1);
    if (fault_ == "throw") throw std::runtime_error("deliberate fault in rollout()");
    if (fault_ == "hang")
      for (;;) ::pause();
    if (fault_ == "nan-fitness") t.fitness = std::numeric_limits<double>::quiet_NaN();
    if (fault_ == "inf-descriptor") t.events.push_back(kMarkerInf);
    if (fault_ == "nan-descriptor") t.events.push_back(kMarkerNan);
    if (fault_ == "cell-out-of-range") t.events.push_back(kMarkerCell);
  }

  int steps_;
  std::string fault_;
  std::vector<std::uint64_t> targets_;  // episode seeds of the faulty offspring
};

constexpr qd::ParamSpec kDescParams[] = {qd::param_int("bins", "20", 1, 10000, "bins per axis over [-1, 1]")};

// The arm's final end-effector position on a bins x bins grid; a marked trace gets a broken answer.
class FaultEndpoint final : public qd::Descriptor {
 public:
  FaultEndpoint(const qd::Config& c, const qd::BuildContext&) : bins_(c.get_int("bins")) {}
  qd::GridSpec grid() const override { return {{bins_, bins_}, {"y", "x"}, {-1.0, -1.0}, {1.0, 1.0}, bins_ * bins_}; }
  void describe(const qd::Trace* traces, std::size_t n, std::int64_t* cells, double* values) const override {
    for (std::size_t i = 0; i < n; ++i) {
      const qd::Trace& t = traces[i];
      const double x = t.main.last()[0], y = t.main.last()[1];
      auto bin = [&](double v) {
        return static_cast<std::int64_t>(
            std::clamp(std::floor((v + 1.0) / 2.0 * static_cast<double>(bins_)), 0.0, static_cast<double>(bins_ - 1)));
      };
      cells[i] = bin(y) * bins_ + bin(x);
      values[2 * i] = y;
      values[2 * i + 1] = x;
      for (int e : t.events) {
        if (e == kMarkerInf) values[2 * i + 1] = std::numeric_limits<double>::infinity();
        if (e == kMarkerNan) values[2 * i] = std::numeric_limits<double>::quiet_NaN();
        if (e == kMarkerCell) cells[i] = bins_ * bins_;
      }
    }
  }

 private:
  std::int64_t bins_;
};

constexpr qd::ParamSpec kMutatorParams[] = {
    qd::param_string("fault", "\"none\"", "none|short|nan|throw|segfault|exit0|quick-exit",
                     "what mutate() does at the chosen iteration (in qdrun's own process)"),
    qd::param_int("fault_loop", "1", 1, 1e9, "loop of the faulty batch"),
    qd::param_int("fault_iteration", "0", 0, 1e9, "iteration of the faulty batch"),
};

class FaultMutator final : public qd::Mutator {
 public:
  FaultMutator(const qd::Config& c, const qd::BuildContext&)
      : fault_(faults_enabled() ? c.get_string("fault") : "none"),
        loop_(static_cast<int>(c.get_int("fault_loop"))),
        iteration_(static_cast<int>(c.get_int("fault_iteration"))) {}
  bool uses_parents() const noexcept override { return false; }
  void mutate(const qd::Parents&, std::size_t count, qd::MutateContext& ctx, qd::Offspring& out) override {
    ctx.rng->fill_uniform(out.theta.data(), static_cast<std::size_t>(out.theta.size()), -1.0, 1.0);
    if (fault_ == "none" || ctx.loop != loop_ || ctx.iteration != iteration_) return;
    if (fault_ == "short") out.theta.conservativeResize(static_cast<Eigen::Index>(count) - 1, out.theta.cols());
    if (fault_ == "nan") out.theta(0, 0) = std::numeric_limits<double>::quiet_NaN();
    if (fault_ == "throw") throw std::runtime_error("deliberate fault in mutate()");
    if (fault_ == "segfault") std::raise(SIGSEGV);
    if (fault_ == "exit0") std::exit(0);
    if (fault_ == "quick-exit") std::quick_exit(0);
  }

 private:
  std::string fault_;
  int loop_, iteration_;
};

constexpr qd::ParamSpec kReprParams[] = {
    qd::param_int("latent", "2", 1, 1e9, "latent size (the first parameters)"),
    qd::param_string("fault", "\"none\"", "none|nan-decode|short-encode", "what the representation returns"),
    qd::param_int("fault_loop", "2", 2, 1e9,
                  "first loop whose offspring see the fault (from 2: the end of loop 0 re-encodes the dataset)"),
};

class FaultLinear final : public qd::Representation {
 public:
  FaultLinear(const qd::Config& c, const qd::BuildContext& b)
      : params_(static_cast<Eigen::Index>(b.policy->param_count())),
        latent_(static_cast<int>(c.get_int("latent"))),
        fault_(faults_enabled() ? c.get_string("fault") : "none"),
        fault_loop_(static_cast<int>(c.get_int("fault_loop"))) {}
  int latent_size() const noexcept override { return latent_; }
  qd::FitReport fit(const qd::Dataset&, const qd::FitContext& ctx) override {
    fitted_loop_ = ctx.loop;
    return {};
  }
  void encode(const qd::Matrix& t, qd::Matrix& z) const override {
    z = t.leftCols(latent_);
    if (active("short-encode")) z.conservativeResize(z.rows() - 1, z.cols());
  }
  void decode(const qd::Matrix& z, qd::Matrix& t) const override {
    t = qd::Matrix::Zero(z.rows(), params_);
    t.leftCols(latent_) = z;
    if (active("nan-decode") && t.size() > 0) t(0, 0) = std::numeric_limits<double>::quiet_NaN();
  }
  void decoder_jacobians(const qd::Matrix& z, std::vector<qd::Matrix>& j) const override {
    j.assign(static_cast<std::size_t>(z.rows()), qd::Matrix::Identity(params_, latent_));
  }
  void save(std::ostream& out) const override { out << fitted_loop_ << '\n'; }
  void load(std::istream& in) override {
    if (!(in >> fitted_loop_)) throw qd::StateError("fault-linear: malformed state");
  }

 private:
  // Offspring of loop n are decoded after fit() of loop n - 1.
  bool active(const char* fault) const { return fault_ == fault && fitted_loop_ + 1 >= fault_loop_; }

  Eigen::Index params_;
  int latent_;
  std::string fault_;
  int fault_loop_;
  int fitted_loop_ = -1;
};

}  // namespace

QD_PLUGIN("fault", "1",
          qd::environment<FaultArm>("fault-arm", "A planar arm that misbehaves on purpose.", kEnvParams,
                                    "fault-endpoint"),
          qd::component<FaultEndpoint>(qd::Kind::kDescriptor, "fault-endpoint",
                                       "fault-arm's end point; breaks its answer for a marked trace.", kDescParams),
          qd::component<FaultMutator>(qd::Kind::kMutator, "fault-mutator",
                                      "A uniform sampler that misbehaves on purpose.", kMutatorParams),
          qd::component<FaultLinear>(qd::Kind::kRepresentation, "fault-linear",
                                     "First-parameters latent code that misbehaves on purpose.", kReprParams))
