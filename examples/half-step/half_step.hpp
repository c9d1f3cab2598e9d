// An out-of-tree mutator: moves each parent halfway towards a uniform random point.
#pragma once

#include <qd/config.hpp>
#include <qd/mutator.hpp>

namespace half_step {

inline constexpr qd::ParamSpec kParams[] = {
    qd::param_float("step", "0.5", 0.0, 1.0, "fraction of the way to the random point")};

class HalfStep final : public qd::Mutator {
 public:
  HalfStep(const qd::Config& c, const qd::BuildContext&) : step_(c.get_float("step")) {}
  std::vector<std::string> metric_names() const override { return {qd::kMixingRatio}; }
  void mutate(const qd::Parents& p, std::size_t count, qd::MutateContext& ctx, qd::Offspring& out) override {
    out.theta = p.theta;
    for (std::size_t i = 0; i < count; ++i)
      for (Eigen::Index k = 0; k < out.theta.cols(); ++k) {
        const double target = ctx.rng->uniform(-1.0, 1.0);
        auto& v = out.theta(static_cast<Eigen::Index>(i), k);
        v += step_ * (target - v);
      }
    out.metrics = {1.0};  // mixing ratio: all made in parameter space
  }

 private:
  double step_;
};

}  // namespace half_step
