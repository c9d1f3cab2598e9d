#include "iso_line_dd_mutator.hpp"

#include <qd/errors.hpp>

namespace qd::line_dd {

IsoLineDdMutator::IsoLineDdMutator(const Config& cfg, const BuildContext&) {
  params_.iso_sigma = cfg.get_float("iso_sigma");
  params_.line_sigma = cfg.get_float("line_sigma");
  params_.pairing = parse_pairing(cfg.get_string("pairing"), "pairing");
}

void IsoLineDdMutator::mutate(const Parents& parents, std::size_t count, MutateContext& ctx, Offspring& out) {
  QD_CHECK(ctx.rng != nullptr, "iso-line-dd: no rng");
  QD_CHECK(static_cast<std::size_t>(parents.theta.rows()) == count, "iso-line-dd: one parent per offspring");
  const int latent = ctx.representation ? ctx.representation->latent_size() : 0;
  out.reset(count, static_cast<std::size_t>(parents.theta.cols()), static_cast<std::size_t>(latent));
  iso_line_dd(parents.theta, 0, static_cast<Eigen::Index>(count), params_, *ctx.rng, out.theta);
  out.metrics = {1.0};  // mixing ratio: everything is made in parameter space
}

}  // namespace qd::line_dd
