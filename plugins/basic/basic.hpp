// The simplest components: representation "none", mutator "iso", samplers "uniform" and "glorot".
#pragma once

#include <qd/config.hpp>
#include <qd/mutator.hpp>
#include <qd/policy.hpp>
#include <qd/representation.hpp>

namespace qd::basic {

inline constexpr ParamSpec kIsoParams[] = {
    param_float("sigma", "0.1", 0.0, kUnbounded, "standard deviation of the Gaussian step added to every parameter"),
};
inline constexpr ParamSpec kUniformParams[] = {
    param_float("low", "-1.0", -kUnbounded, kUnbounded, "lower bound of every parameter"),
    param_float("high", "1.0", -kUnbounded, kUnbounded, "upper bound of every parameter"),
};

// No model: parameter-space algorithms. latent_size() is 0, so the core never calls the rest.
class NoRepresentation final : public Representation {
 public:
  NoRepresentation(const Config&, const BuildContext&) {}
  int latent_size() const noexcept override { return 0; }
  FitReport fit(const Dataset&, const FitContext&) override { return {}; }
  void encode(const Matrix&, Matrix&) const override;
  void decode(const Matrix&, Matrix&) const override;
  void decoder_jacobians(const Matrix&, std::vector<Matrix>&) const override;
  void save(std::ostream&) const override {}
  void load(std::istream&) override {}
};

// MAPE-Iso: θ′ = θ + σ·ε.
class IsoMutator final : public Mutator {
 public:
  IsoMutator(const Config& cfg, const BuildContext&);
  std::vector<std::string> metric_names() const override { return {kMixingRatio}; }
  void mutate(const Parents& parents, std::size_t count, MutateContext& ctx, Offspring& out) override;

 private:
  double sigma_;
};

// ps-uniform: every parameter i.i.d. U(low, high); parents ignored.
class UniformSampler final : public Mutator {
 public:
  UniformSampler(const Config& cfg, const BuildContext&);
  bool uses_parents() const noexcept override { return false; }
  void mutate(const Parents&, std::size_t count, MutateContext& ctx, Offspring& out) override;

 private:
  double low_, high_;
};

// ps-glorot: layer l i.i.d. N(0, 1/(r_l + c_l)) with r_l = n_in + 1, c_l = n_out.
class GlorotSampler final : public Mutator {
 public:
  GlorotSampler(const Config& cfg, const BuildContext& ctx);
  bool uses_parents() const noexcept override { return false; }
  void mutate(const Parents&, std::size_t count, MutateContext& ctx, Offspring& out) override;
  // Standard deviation used for layer l.
  double layer_std(int l) const { return stds_[static_cast<std::size_t>(l)]; }

 private:
  PolicyShape shape_;
  std::vector<double> stds_;
};

}  // namespace qd::basic
