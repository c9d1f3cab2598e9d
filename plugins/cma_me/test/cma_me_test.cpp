// CMA-ES against the theory of evolution strategies, and CMA-ME's emitters against the rules of the
// CMA-ME paper: the convergence rate on the sphere, the covariance learning the inverse Hessian of
// an ellipsoid, the improvement ranking, filter selection, restarts, and the shipped conformance
// checks (which include the checkpoint round trip).
#include "cma_es.hpp"
#include "cma_me_mutator.hpp"

#include <qd/errors.hpp>
#include <qd/testing/conformance.hpp>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

namespace {

using namespace qd;
using namespace qd::cma_me;

// E[X_(i)], the i-th largest of lambda standard normals (i = 1 .. lambda), by quadrature.
double normal_order_statistic(int i, int lambda) {
  double sum = 0.0;
  const double h = 1e-3;
  const double log_choose = std::lgamma(lambda + 1.0) - std::lgamma(i) - std::lgamma(lambda - i + 1.0);
  for (double x = -12.0; x <= 12.0; x += h) {
    const double cdf = 0.5 * std::erfc(-x / std::sqrt(2.0));
    const double pdf = std::exp(-0.5 * x * x) / std::sqrt(2.0 * M_PI);
    if (cdf <= 0.0 || cdf >= 1.0) continue;
    sum += x * std::exp(log_choose + (lambda - i) * std::log(cdf) + (i - 1) * std::log1p(-cdf)) * pdf * h;
  }
  return sum;
}

// The progress rate of weighted recombination at the optimal step size, per generation, in ln f of
// the sphere (Arnold, "Weighted multirecombination evolution strategies", 2006; Hansen's tutorial,
// Sec. 3): phi* = mu_eff (sum w_i E_i:lambda)^2 / 2, and ln f = 2 ln R falls by 2 phi* / n.
double optimal_log_rate(int n, int lambda) {
  const int mu = lambda / 2;
  std::vector<double> w(static_cast<std::size_t>(mu));
  for (int i = 0; i < mu; ++i) w[static_cast<std::size_t>(i)] = std::log(mu + 0.5) - std::log(i + 1.0);
  const double total = std::accumulate(w.begin(), w.end(), 0.0);
  double mueff = 0.0, gain = 0.0;
  for (int i = 0; i < mu; ++i) {
    const double wi = w[static_cast<std::size_t>(i)] / total;
    mueff += wi * wi;
    gain += wi * normal_order_statistic(i + 1, lambda);
  }
  mueff = 1.0 / mueff;
  return 2.0 * (mueff * gain * gain / 2.0) / n;
}

// Runs CMA-ES with truncation selection on f and returns ln f(mean) per generation.
template <class F>
std::vector<double> minimise(F f, int n, std::uint64_t seed, int generations, CmaEs* keep = nullptr) {
  const auto lambda = static_cast<std::size_t>(4 + std::floor(3 * std::log(n)));
  CmaEs es(static_cast<std::size_t>(n), lambda, 0.5);
  const Vector start = Vector::Ones(n);
  es.reset(start.data());
  Matrix x(static_cast<Eigen::Index>(lambda), n);
  std::vector<double> trace;
  for (int g = 0; g < generations; ++g) {
    Rng rng(seed, Stream::kPlugin, static_cast<std::uint64_t>(g));
    es.sample(rng, x.data());
    std::vector<std::size_t> order(lambda);
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::vector<double> fx(lambda);
    for (std::size_t k = 0; k < lambda; ++k) fx[k] = f(Vector(x.row(static_cast<Eigen::Index>(k)).transpose()));
    std::stable_sort(order.begin(), order.end(), [&](auto a, auto b) { return fx[a] < fx[b]; });
    Matrix best(static_cast<Eigen::Index>(lambda / 2), n);
    for (std::size_t i = 0; i < lambda / 2; ++i)
      best.row(static_cast<Eigen::Index>(i)) = x.row(static_cast<Eigen::Index>(order[i]));
    es.tell(best);
    trace.push_back(std::log(f(es.mean())));
  }
  if (keep) *keep = es;
  return trace;
}

// Least-squares slope of ln f over the generations where f(mean) is between 1e-4 and 1e-14 (the
// linear phase, after the step size has adapted).
double linear_phase_slope(const std::vector<double>& lnf) {
  double sx = 0, sy = 0, sxx = 0, sxy = 0, m = 0;
  for (std::size_t g = 0; g < lnf.size(); ++g) {
    if (lnf[g] > std::log(1e-4) || lnf[g] < std::log(1e-14)) continue;
    sx += g, sy += lnf[g], sxx += double(g) * g, sxy += g * lnf[g], ++m;
  }
  EXPECT_GT(m, 10) << "too few generations in the linear phase";
  return (m * sxy - sx * sy) / (m * sxx - sx * sx);
}

// On the sphere, ln f falls linearly. The rate per generation of CMA-ES with its default parameters
// is a known quantity: 0.139 at n = 10 and 0.073 at n = 30 (mean of 4 seeds of an independent NumPy
// transcription of pycma's purecma, Hansen's reference implementation, with these update equations),
// about 35-40 % of the rate at the optimal step size (the textbook formula above: 0.39 and 0.20),
// because cumulative step-size adaptation settles at about twice the optimal normalised step on the
// sphere at small n. A wrong weight, learning rate or step-size rule moves it far outside 20 %.
TEST(CmaEs, ConvergesOnTheSphereAtTheTextbookRate) {
  const std::vector<std::pair<int, double>> reference = {{10, 0.139}, {30, 0.073}};
  for (const auto& [n, expected] : reference) {
    const auto lambda = static_cast<int>(4 + std::floor(3 * std::log(n)));
    const double optimal = optimal_log_rate(n, lambda);
    double measured = 0.0;
    for (std::uint64_t seed = 1; seed <= 4; ++seed)
      measured -= linear_phase_slope(minimise([](const Vector& v) { return v.squaredNorm(); }, n, seed, 40 * n)) / 4.0;
    EXPECT_NEAR(measured, expected, 0.2 * expected) << "n = " << n;
    EXPECT_GT(measured, 0.3 * optimal) << "n = " << n << ": optimal-step rate " << optimal;
    EXPECT_LT(measured, optimal) << "n = " << n << ": optimal-step rate " << optimal;
  }
}

// On an ellipsoid of condition 1e6, C learns the inverse Hessian: its condition number approaches 1e6
// and its eigenvectors the axes; without covariance adaptation the rate would fall a thousandfold.
TEST(CmaEs, CovarianceLearnsTheInverseHessianOfAnEllipsoid) {
  const int n = 8;
  Vector h(n);
  for (int i = 0; i < n; ++i) h[i] = std::pow(1e6, double(i) / (n - 1));
  CmaEs es(n, 4 + static_cast<std::size_t>(std::floor(3 * std::log(n))), 0.5);
  const std::vector<double> lnf = minimise([&](const Vector& v) { return v.cwiseProduct(h).dot(v); }, n, 7, 1500, &es);
  EXPECT_LT(lnf.back(), std::log(1e-10)) << "did not converge";
  const Eigen::SelfAdjointEigenSolver<Matrix> eig(es.covariance());
  const double condition = eig.eigenvalues().maxCoeff() / eig.eigenvalues().minCoeff();
  EXPECT_GT(condition, 1e6 / 5);
  EXPECT_LT(condition, 1e6 * 5);
  // C ~ H^-1: the variance along axis i times h_i is about constant.
  const Matrix& c = es.covariance();
  std::vector<double> scaled;
  for (int i = 0; i < n; ++i) scaled.push_back(c(i, i) * h[i]);
  const auto [lo, hi] = std::minmax_element(scaled.begin(), scaled.end());
  EXPECT_LT(*hi / *lo, 10.0);
}

OffspringResult result(Outcome o, double fitness, double previous = std::nan("")) {
  OffspringResult r;
  r.outcome = o;
  r.fitness = fitness;
  r.previous = previous;
  r.cell = o == Outcome::kInvalid ? -1 : 0;
  return r;
}

// New cells first (by fitness), then offspring that entered an occupied cell (by the fitness change),
// then the rest (by change), invalid evaluations last; ties keep batch order.
TEST(CmaMe, ImprovementRankingOrdersByStageThenValue) {
  const std::vector<OffspringResult> r = {
      result(Outcome::kDiscarded, 1.0, 2.0),    // 0: change -1
      result(Outcome::kImproved, 5.0, 4.0),     // 1: change +1
      result(Outcome::kNewCell, 3.0),           // 2
      result(Outcome::kInvalid, std::nan("")),  // 3
      result(Outcome::kImproved, 9.0, 6.0),     // 4: change +3
      result(Outcome::kNewCell, 7.0),           // 5
      result(Outcome::kReplaced, 1.0, 1.5),     // 6: entered, change -0.5
      result(Outcome::kDiscarded, 1.0, 1.5),    // 7: change -0.5
  };
  EXPECT_EQ(improvement_ranking(r, 0, r.size()), (std::vector<std::size_t>{5, 2, 4, 1, 6, 7, 0, 3}));
  EXPECT_EQ(improvement_ranking(r, 4, 8), (std::vector<std::size_t>{5, 4, 6, 7}));
}

// A mutator with 2 emitters of 4 offspring on 3 parameters, run as the core runs it.
struct Driver {
  explicit Driver(const std::string& selection = "filter", const std::string& restart = "no-improvement") {
    Config c = defaults_of(kCmaMeParams, "mutator");
    c.set_int("emitters", 2);
    c.set_string("selection", selection);
    c.set_string("restart", restart);
    BuildContext ctx;
    ctx.batch = 8;
    m = std::make_unique<CmaMeMutator>(c, ctx);
    parents.theta = Matrix::Zero(8, 3);
    for (int i = 0; i < 8; ++i) parents.theta.row(i).setConstant(10.0 * (i + 1));
    archive = std::make_unique<qd::testing::Elites>(100, 3, 1);
  }
  Offspring mutate(int it) {
    Rng rng(1, Stream::kMutation, 1, static_cast<std::uint64_t>(it));
    MutateContext ctx{1, it, &rng, &none, archive.get()};
    Offspring out;
    out.reset(8, 3, 0);
    m->mutate(parents, 8, ctx, out);
    return out;
  }
  void feedback(const std::vector<OffspringResult>& r) {
    results = r;
    Feedback fb;
    fb.offspring = 8;
    fb.results = &results;
    m->feedback(fb);
  }
  std::unique_ptr<CmaMeMutator> m;
  Parents parents;
  std::unique_ptr<qd::testing::Elites> archive;
  qd::testing::detail::NoLatentSpace none;
  std::vector<OffspringResult> results;
};

// Emitter e starts at parent e; with filter selection its CMA-ES moves to the weighted mean of the
// offspring that entered the archive, best first; an emitter none of whose offspring entered
// restarts at the next mutate() from that iteration's parent, and the restarts metric counts it.
TEST(CmaMe, FilterSelectionAndRestartFromAFreshElite) {
  Driver d;
  const Offspring first = d.mutate(0);
  EXPECT_EQ(d.m->emitter(0).mean(), Vector::Constant(3, 10.0));
  EXPECT_EQ(d.m->emitter(1).mean(), Vector::Constant(3, 20.0));
  EXPECT_EQ(first.metrics, (std::vector<double>{2.0, 0.5}));
  // Emitter 0: offspring 2 (new cell) and 0 (improved) entered; emitter 1: nothing entered.
  std::vector<OffspringResult> r(8, result(Outcome::kDiscarded, 0.0, 1.0));
  r[0] = result(Outcome::kImproved, 2.0, 1.0);
  r[2] = result(Outcome::kNewCell, 0.5);
  d.feedback(r);
  const double w0 = std::log(2.5) - std::log(1.0), w1 = std::log(2.5) - std::log(2.0);
  const Vector expected = (w0 * first.theta.row(2) + w1 * first.theta.row(0)).transpose() / (w0 + w1);
  EXPECT_TRUE(d.m->emitter(0).mean().isApprox(expected, 1e-14)) << d.m->emitter(0).mean().transpose();
  d.parents.theta.row(1).setConstant(-7.0);  // the fresh elite emitter 1 restarts from
  const Offspring second = d.mutate(1);
  EXPECT_EQ(d.m->emitter(1).mean(), Vector::Constant(3, -7.0));
  EXPECT_EQ(d.m->emitter(1).sigma(), 0.5);
  EXPECT_EQ(d.m->restarts(), 3u);
  EXPECT_EQ(second.metrics[0], 3.0);
  EXPECT_TRUE(d.m->emitter(0).mean().isApprox(expected, 1e-14)) << "emitter 0 did not restart";
}

// "mu" selection updates with the best lambda / 2 of the ranking even when nothing entered, and
// "basic" restarts do not react to an emitter without archive entries.
TEST(CmaMe, MuSelectionAndBasicRestart) {
  Driver d("mu", "basic");
  const Offspring first = d.mutate(0);
  std::vector<OffspringResult> r(8, result(Outcome::kDiscarded, 0.0, 1.0));
  r[1] = result(Outcome::kDiscarded, 0.5, 1.0);  // emitter 0's ranking is not flat
  r[5] = result(Outcome::kDiscarded, 0.9, 1.0);  // emitter 1's best, then offspring 6
  r[6] = result(Outcome::kDiscarded, 0.1, 1.0);
  d.feedback(r);
  // Weights for mu = 2: ln 2.5 - ln 1 and ln 2.5 - ln 2, normalised.
  const double w0 = std::log(2.5), w1 = std::log(2.5) - std::log(2.0);
  const Vector weighted = (w0 * first.theta.row(5) + w1 * first.theta.row(6)).transpose() / (w0 + w1);
  EXPECT_TRUE(d.m->emitter(1).mean().isApprox(weighted, 1e-14)) << d.m->emitter(1).mean().transpose();
  d.mutate(1);
  EXPECT_EQ(d.m->restarts(), 2u) << "no restart under the basic rule";
}

TEST(CmaMe, ABatchThatIsNoMultipleOfTheEmittersIsAConfigError) {
  Config c = defaults_of(kCmaMeParams, "mutator");
  BuildContext ctx;
  ctx.batch = 100;
  try {
    CmaMeMutator m(c, ctx);
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.key(), "emitters");
    EXPECT_NE(std::string(e.what()).find("batch = 100 must be a multiple of emitters = 15"), std::string::npos);
  }
}

TEST(CmaMe, Conforms) {
  Config c = defaults_of(kCmaMeParams, "mutator");
  c.set_int("emitters", 4);
  qd::testing::MutatorCase mc;
  mc.iterations = 6;
  const qd::testing::Report report =
      qd::testing::check_mutator([&] { return std::make_unique<CmaMeMutator>(c, BuildContext{}); }, mc);
  EXPECT_TRUE(report.ok()) << report;
}

}  // namespace
