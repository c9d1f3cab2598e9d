// The linear-projection (LP) benchmark of the CMA-ME paper (Fontaine, Togelius, Nikolaidis, Hoover,
// "Covariance Matrix Adaptation for the Rapid Illumination of Behavior Space", GECCO 2020, Sec. 4),
// as pyribs's sphere example computes it:
//
//  * a solution is a plain vector x of n parameters (EnvironmentInfo::parameters: no policy network);
//  * fitness: the sphere or the Rastrigin function of x - 2.048 (the optimum moved to 0.4 * 5.12 in
//    every coordinate), normalised to 100 * (1 - f(x) / f(-5.12, ..., -5.12)): 100 at the optimum,
//    0 at the corner (-5.12, ...); below 0 only far outside [-5.12, 5.12]^n;
//  * measures: the sums of clip(x_i) over the first floor(n/2) and over the remaining coordinates,
//    clip(v) = v inside [-5.12, 5.12] and 5.12 / v outside, so that the edges of the measure space
//    are hard to reach (the "distortion" the benchmark tests).
//
// One evaluation is one "episode" of one step; the trace's main table has one row (measure 0,
// measure 1), which the descriptor "lp-measures" bins on a bins x bins grid over
// [-5.12 floor(n/2), 5.12 floor(n/2)] x [-5.12 ceil(n/2), 5.12 ceil(n/2)].
#pragma once

#include <qd/config.hpp>
#include <qd/descriptor.hpp>
#include <qd/environment.hpp>

#include <cstdint>

namespace qd::lp {

inline constexpr double kClipBound = 5.12;
inline constexpr double kOptimum = 0.4 * kClipBound;  // 2.048 in every coordinate
inline constexpr double kRastriginA = 10.0;

inline constexpr ParamSpec kLpParams[] = {
    param_int("parameters", "100", 2, 1000000, "n, the solution's dimension (the CMA-ME paper: 20 and 100)"),
};
inline constexpr ParamSpec kMeasuresParams[] = {
    param_int("bins", "100", 1, 100000, "bins per measure (pyribs's benchmark: 100; the CMA-ME paper: 500)"),
};

enum class Function { kSphere, kRastrigin };

// clip(v): v inside [-5.12, 5.12], 5.12 / v outside.
double clip(double v) noexcept;
// The raw function of x (lower is better): sphere sum (x_i - 2.048)^2, Rastrigin
// A n + sum ((x_i - 2.048)^2 - A cos(2 pi (x_i - 2.048))).
double raw(Function f, const double* x, std::size_t n) noexcept;
// 100 * (1 - raw(x) / raw(-5.12, ..., -5.12)).
double normalised_fitness(Function f, const double* x, std::size_t n) noexcept;

class LpEnvironment : public Environment {
 public:
  LpEnvironment(Function f, const Config& cfg, const BuildContext&);
  EnvironmentInfo info() const override;
  void rollout(const RolloutBatch& batch, Trace* traces) const override;

 private:
  Function f_;
  std::size_t n_;
};

// The two components: "lp-sphere" and "lp-rastrigin".
class LpSphere final : public LpEnvironment {
 public:
  LpSphere(const Config& cfg, const BuildContext& ctx) : LpEnvironment(Function::kSphere, cfg, ctx) {}
};
class LpRastrigin final : public LpEnvironment {
 public:
  LpRastrigin(const Config& cfg, const BuildContext& ctx) : LpEnvironment(Function::kRastrigin, cfg, ctx) {}
};

// The two measures on a bins x bins grid; the solution's dimension comes from the policy shape
// (a direct parameter vector, as lp-sphere and lp-rastrigin give).
class MeasuresDescriptor final : public Descriptor {
 public:
  MeasuresDescriptor(const Config& cfg, const BuildContext& ctx);
  GridSpec grid() const override;
  void describe(const Trace* traces, std::size_t n, std::int64_t* cells, double* values) const override;
  std::int64_t cell_of(double m0, double m1) const noexcept;

 private:
  std::int64_t bins_;
  double half0_, half1_;  // the measures' ranges: [-half, half]
};

}  // namespace qd::lp
