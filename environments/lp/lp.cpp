#include "lp.hpp"

#include <qd/errors.hpp>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace qd::lp {

double clip(double v) noexcept {
  return std::fabs(v) <= kClipBound ? v : kClipBound / v;
}

double raw(Function f, const double* x, std::size_t n) noexcept {
  double sum = f == Function::kRastrigin ? kRastriginA * static_cast<double>(n) : 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double v = x[i] - kOptimum;
    sum += v * v;
    if (f == Function::kRastrigin) sum -= kRastriginA * std::cos(2.0 * M_PI * v);
  }
  return sum;
}

double normalised_fitness(Function f, const double* x, std::size_t n) noexcept {
  const std::vector<double> corner(n, -kClipBound);
  return 100.0 * (1.0 - raw(f, x, n) / raw(f, corner.data(), n));
}

LpEnvironment::LpEnvironment(Function f, const Config& cfg, const BuildContext&)
    : f_(f), n_(static_cast<std::size_t>(cfg.get_int("parameters"))) {}

EnvironmentInfo LpEnvironment::info() const {
  EnvironmentInfo info;
  info.max_steps = 1;
  info.has_fitness = true;
  // No finite lower bound (the normalised fitness falls below 0 far outside [-5.12, 5.12]^n): the
  // experiment files give pyribs's QD-score offset, 0.
  info.parameters = static_cast<int>(n_);
  return info;
}

void LpEnvironment::rollout(const RolloutBatch& batch, Trace* traces) const {
  QD_CHECK(batch.shape->is_direct() && batch.shape->param_count() == n_,
           "lp: the core hands over plain vectors of info().parameters values");
  const std::size_t n = n_;
  const std::size_t half = n / 2;
  const double worst = [&] {
    const std::vector<double> corner(n, -kClipBound);
    return raw(f_, corner.data(), n);
  }();
  for (std::size_t i = batch.begin; i < batch.end; ++i) {
    const double* x = batch.row(i);
    Trace& t = traces[i];
    t.main.reset(2);
    if (!std::all_of(x, x + n, [](double v) { return std::isfinite(v); })) {
      t.status = EvalStatus::kInvalidAction;
      t.message = "non-finite solution";
      continue;
    }
    double m0 = 0.0, m1 = 0.0;
    for (std::size_t k = 0; k < half; ++k) m0 += clip(x[k]);
    for (std::size_t k = half; k < n; ++k) m1 += clip(x[k]);
    t.main.push(m0, m1);
    t.fitness = 100.0 * (1.0 - raw(f_, x, n) / worst);
    t.steps = 1;
  }
}

MeasuresDescriptor::MeasuresDescriptor(const Config& cfg, const BuildContext& ctx) : bins_(cfg.get_int("bins")) {
  if (ctx.policy == nullptr || !ctx.policy->is_direct())
    throw InputError(
        "descriptor 'lp-measures' needs an environment that evaluates plain parameter vectors (lp-sphere, "
        "lp-rastrigin)");
  const std::size_t n = ctx.policy->param_count();
  half0_ = kClipBound * static_cast<double>(n / 2);
  half1_ = kClipBound * static_cast<double>(n - n / 2);
}

GridSpec MeasuresDescriptor::grid() const {
  GridSpec g;
  g.shape = {bins_, bins_};
  g.names = {"measure_0", "measure_1"};
  g.lower = {-half0_, -half1_};
  g.upper = {half0_, half1_};
  g.cells = bins_ * bins_;
  return g;
}

std::int64_t MeasuresDescriptor::cell_of(double m0, double m1) const noexcept {
  auto bin = [&](double v, double half) {
    const double b = std::floor((v + half) / (2.0 * half) * static_cast<double>(bins_));
    return static_cast<std::int64_t>(std::clamp(b, 0.0, static_cast<double>(bins_ - 1)));
  };
  return bin(m0, half0_) * bins_ + bin(m1, half1_);
}

void MeasuresDescriptor::describe(const Trace* traces, std::size_t n, std::int64_t* cells, double* values) const {
  for (std::size_t i = 0; i < n; ++i) {
    const Series& m = traces[i].main;
    if (m.rows() != 1 || m.cols != 2) {
      cells[i] = -1;
      continue;
    }
    values[2 * i] = m.at(0, 0);
    values[2 * i + 1] = m.at(0, 1);
    cells[i] = cell_of(m.at(0, 0), m.at(0, 1));
  }
}

}  // namespace qd::lp
