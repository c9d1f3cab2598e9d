// PoMS latent-space mutators (the paper, Sec. 3; README.md). They use only the Representation interface
// (encode, decode, decoder_vjp), so they work with any model that has a latent space: the
// autoencoder (PoMS, PoMS-no-jacobian) or PCA (PoMS-PCA).
#pragma once

#include <qd/config.hpp>
#include <qd/mutator.hpp>

#include <iosfwd>
#include <string>
#include <vector>

namespace qd::poms {

extern const ParamSpec kPomsParams[3];
extern const ParamSpec kNoJacobianParams[1];

// How `sigma` enters the latent covariance Σ_z.
enum class SigmaMeaning {
  kVariance,  // reference: Σ_z = σ·JᵀJ (σ is a variance here, a std in parameter space)
  kStd,       // Σ_z = σ²·JᵀJ (σ is a std in both branches)
};

// Which reconstruction errors decide the parameter-space / latent-space split.
enum class ThresholdMode {
  kArchiveMean,  // reference: mean of the archive's stored (stale) errors, fixed at begin_loop;
                 // parents are compared by their stored errors
  kRefreshed,    // errors recomputed with the current model: threshold = mean over all elites at
                 // begin_loop, parents compared by their current errors
};

// "poms": region mix. Parents whose reconstruction error exceeds the threshold get isotropic
// parameter-space noise; the others are re-encoded and moved by z' = z + Jᵀξ, ξ ~ N(0, s²I_P),
// which has covariance s²·JᵀJ exactly, then decoded.
class PomsMutator final : public Mutator {
 public:
  PomsMutator(const Config& cfg, const BuildContext& ctx);
  PomsMutator(double sigma, SigmaMeaning meaning, ThresholdMode threshold);

  bool needs_latent() const noexcept override { return true; }
  std::vector<std::string> metric_names() const override { return {"threshold", kMixingRatio}; }

  void begin_loop(const LoopContext& ctx) override;
  void mutate(const Parents& parents, std::size_t count, MutateContext& ctx, Offspring& out) override;

  void save(std::ostream& out) const override;
  void load(std::istream& in) override;

  double threshold() const noexcept { return threshold_; }
  // Standard deviation of ξ in z' = z + Jᵀξ.
  double latent_noise_std() const noexcept;
  // The parameter-space set H for these errors (README.md, step 1), in index order.
  std::vector<std::size_t> parameter_space_set(const Vector& errors) const;

 private:
  double sigma_;
  SigmaMeaning meaning_;
  ThresholdMode mode_;
  double threshold_ = 0.0;
};

// "poms-no-jacobian": every offspring is z' = Enc(θ) + scale·s ⊙ ε with s the population std of
// the encoded dataset per latent coordinate (computed at begin_loop), θ' = Dec(z').
class NoJacobianMutator final : public Mutator {
 public:
  NoJacobianMutator(const Config& cfg, const BuildContext& ctx);
  explicit NoJacobianMutator(double scale);

  bool needs_latent() const noexcept override { return true; }
  std::vector<std::string> metric_names() const override { return {kMixingRatio}; }

  void begin_loop(const LoopContext& ctx) override;
  void mutate(const Parents& parents, std::size_t count, MutateContext& ctx, Offspring& out) override;

  void save(std::ostream& out) const override;
  void load(std::istream& in) override;

  const Vector& latent_std() const noexcept { return latent_std_; }

 private:
  double scale_;
  Vector latent_std_;
};

}  // namespace qd::poms
