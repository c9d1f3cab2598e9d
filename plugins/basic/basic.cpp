#include "basic.hpp"

#include <qd/errors.hpp>

#include <cmath>

namespace qd::basic {

void NoRepresentation::encode(const Matrix&, Matrix&) const {
  QD_CHECK(false, "representation 'none' has no latent space");
}
void NoRepresentation::decode(const Matrix&, Matrix&) const {
  QD_CHECK(false, "representation 'none' has no latent space");
}
void NoRepresentation::decoder_jacobians(const Matrix&, std::vector<Matrix>&) const {
  QD_CHECK(false, "representation 'none' has no latent space");
}

IsoMutator::IsoMutator(const Config& cfg, const BuildContext&) : sigma_(cfg.get_float("sigma")) {}

void IsoMutator::mutate(const Parents& parents, std::size_t count, MutateContext& ctx, Offspring& out) {
  QD_CHECK(static_cast<std::size_t>(parents.theta.rows()) == count, "iso mutates one offspring per parent");
  out.theta = parents.theta;
  ctx.rng->add_normal(out.theta.data(), static_cast<std::size_t>(out.theta.size()), sigma_);
  out.metrics = {1.0};  // mixing ratio
}

UniformSampler::UniformSampler(const Config& cfg, const BuildContext&)
    : low_(cfg.get_float("low")), high_(cfg.get_float("high")) {
  if (!(low_ < high_)) throw ConfigError("high", "high must be greater than low");
}

void UniformSampler::mutate(const Parents&, std::size_t count, MutateContext& ctx, Offspring& out) {
  QD_CHECK(static_cast<std::size_t>(out.theta.rows()) == count, "offspring batch was not sized by the core");
  ctx.rng->fill_uniform(out.theta.data(), static_cast<std::size_t>(out.theta.size()), low_, high_);
}

GlorotSampler::GlorotSampler(const Config&, const BuildContext& ctx) {
  QD_CHECK(ctx.policy != nullptr, "glorot needs the policy shape");
  if (ctx.policy->is_direct())
    throw InputError(
        "glorot draws the layers of a policy network, but the environment evaluates plain parameter vectors "
        "(it has no network); use \"uniform\"");
  shape_ = *ctx.policy;
  for (int l = 0; l < shape_.layers(); ++l)
    stds_.push_back(std::sqrt(1.0 / static_cast<double>(shape_.layer_inputs(l) + 1 + shape_.layer_outputs(l))));
}

void GlorotSampler::mutate(const Parents&, std::size_t count, MutateContext& ctx, Offspring& out) {
  QD_CHECK(static_cast<std::size_t>(out.theta.rows()) == count, "offspring batch was not sized by the core");
  for (Eigen::Index i = 0; i < out.theta.rows(); ++i) {
    double* row = out.theta.row(i).data();
    for (int l = 0; l < shape_.layers(); ++l) {
      const std::size_t begin = shape_.layer_offset(l);
      const std::size_t end = shape_.layer_offset(l + 1);
      ctx.rng->fill_normal(row + begin, end - begin, stds_[static_cast<std::size_t>(l)]);
    }
  }
}

}  // namespace qd::basic
