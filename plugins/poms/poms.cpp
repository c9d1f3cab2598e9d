#include "poms.hpp"

#include <qd/errors.hpp>
#include <qd/state_io.hpp>

#include <cmath>
#include <utility>

namespace qd::poms {

const ParamSpec kPomsParams[3] = {
    param_float("sigma", "0.1", 0.0, kUnbounded,
                "noise scale: std of the parameter-space step; in the latent step a variance (reference, "
                "Sigma_z = sigma J^T J) or a std (sigma_meaning = \"std\")"),
    param_string("sigma_meaning", "\"variance\"", "variance|std",
                 "variance: Sigma_z = sigma J^T J (reference); std: Sigma_z = sigma^2 J^T J"),
    param_string("threshold", "\"archive-mean\"", "archive-mean|refreshed",
                 "archive-mean: mean of the stored (stale) archive errors at loop start, parents compared by "
                 "stored errors (reference); refreshed: both recomputed with the current model"),
};

const ParamSpec kNoJacobianParams[1] = {
    param_float("scale", "1.0", 0.0, kUnbounded,
                "extension: multiplies the per-coordinate latent std s (1 = reference; sigma is not used)"),
};

namespace {

SigmaMeaning parse_meaning(const std::string& s) {
  if (s == "variance") return SigmaMeaning::kVariance;
  if (s == "std") return SigmaMeaning::kStd;
  throw ConfigError("sigma_meaning", "unknown value \"" + s + "\" (variance|std)");
}

ThresholdMode parse_threshold(const std::string& s) {
  if (s == "archive-mean") return ThresholdMode::kArchiveMean;
  if (s == "refreshed") return ThresholdMode::kRefreshed;
  throw ConfigError("threshold", "unknown value \"" + s + "\" (archive-mean|refreshed)");
}

const Representation& latent_model(const Representation* rep, const char* who) {
  QD_CHECK(rep != nullptr, who);
  QD_CHECK(rep->latent_size() > 0, who);
  return *rep;
}

}  // namespace

// ---- poms -------------------------------------------------------------------------------------

PomsMutator::PomsMutator(const Config& cfg, const BuildContext&)
    : PomsMutator(cfg.get_float("sigma"), parse_meaning(cfg.get_string("sigma_meaning")),
                  parse_threshold(cfg.get_string("threshold"))) {}

PomsMutator::PomsMutator(double sigma, SigmaMeaning meaning, ThresholdMode threshold)
    : sigma_(sigma), meaning_(meaning), mode_(threshold) {
  if (!(sigma_ >= 0.0) || !std::isfinite(sigma_)) throw ConfigError("sigma", "must be finite and >= 0");
}

double PomsMutator::latent_noise_std() const noexcept {
  // ξ ~ N(0, v·I_P) gives Cov(Jᵀξ) = v·JᵀJ: v = σ reproduces the reference's σ·JᵀJ.
  return meaning_ == SigmaMeaning::kVariance ? std::sqrt(sigma_) : sigma_;
}

void PomsMutator::begin_loop(const LoopContext& ctx) {
  QD_CHECK(ctx.archive != nullptr, "poms: begin_loop needs the archive");
  if (mode_ == ThresholdMode::kArchiveMean) {
    // Reference (README.md, threshold): the stored errors are those computed when each elite entered the
    // archive, never refreshed after retraining; latent-space offspring carry 0.
    threshold_ = ctx.archive->mean_recn_error();
    return;
  }
  const Representation& rep = latent_model(ctx.representation, "poms: begin_loop needs a latent representation");
  const ArchiveView& archive = *ctx.archive;
  if (archive.size() == 0) {
    threshold_ = 0.0;
    return;
  }
  const auto p = static_cast<Eigen::Index>(archive.param_count());
  Matrix elites(static_cast<Eigen::Index>(archive.size()), p);
  for (std::size_t slot = 0; slot < archive.size(); ++slot)
    elites.row(static_cast<Eigen::Index>(slot)) = Eigen::Map<const RowVector>(archive.params(slot), p);
  Vector errors;
  rep.reconstruction_errors(elites, errors);
  threshold_ = errors.mean();
}

std::vector<std::size_t> PomsMutator::parameter_space_set(const Vector& errors) const {
  const auto n = static_cast<std::size_t>(errors.size());
  std::vector<std::size_t> high;
  if (n == 0) return high;
  for (std::size_t i = 0; i < n; ++i)
    if (errors(static_cast<Eigen::Index>(i)) > threshold_) high.push_back(i);
  // Reference rules, in this order: never an all-latent batch, never an all-parameter batch.
  if (high.empty()) high.push_back(0);
  if (high.size() == n) high.pop_back();
  return high;
}

void PomsMutator::mutate(const Parents& parents, std::size_t count, MutateContext& ctx, Offspring& out) {
  const Representation& rep = latent_model(ctx.representation, "poms: needs a representation with a latent space");
  QD_CHECK(ctx.rng != nullptr, "poms: mutate needs an rng");
  QD_CHECK(static_cast<std::size_t>(parents.theta.rows()) == count, "poms: one parent per offspring expected");
  const Eigen::Index p = parents.theta.cols();
  const int ld = rep.latent_size();
  out.reset(count, static_cast<std::size_t>(p), static_cast<std::size_t>(ld));
  out.latent.setZero();
  out.metrics = {threshold_, 0.0};  // threshold, mixing ratio
  if (count == 0) return;

  Vector errors;
  if (mode_ == ThresholdMode::kArchiveMean) {
    QD_CHECK(static_cast<std::size_t>(parents.recn_error.size()) == count, "poms: parents lack stored errors");
    errors = parents.recn_error;
  } else {
    rep.reconstruction_errors(parents.theta, errors);
  }
  const std::vector<std::size_t> high = parameter_space_set(errors);
  std::vector<char> is_high(count, 0);
  for (std::size_t i : high) is_high[i] = 1;

  Rng& rng = *ctx.rng;
  // Parameter-space branch, in index order: θ' = θ + σε (σ is a std here). The core encodes these.
  Eigen::Index row = 0;
  for (std::size_t i : high) {
    rng.fill_normal(out.theta.row(row).data(), static_cast<std::size_t>(p), sigma_);
    out.theta.row(row) += parents.theta.row(static_cast<Eigen::Index>(i));
    ++row;
  }

  // Latent-space branch: re-encode the parents with the current model (the stored latent is not
  // used), z' = z + Jᵀξ, θ' = Dec(z').
  const auto n_low = static_cast<Eigen::Index>(count - high.size());
  if (n_low > 0) {
    Matrix low(n_low, p);
    Eigen::Index k = 0;
    for (std::size_t i = 0; i < count; ++i)
      if (!is_high[i]) low.row(k++) = parents.theta.row(static_cast<Eigen::Index>(i));
    Matrix z, xi(n_low, p), step, decoded;
    rep.encode(low, z);
    rng.fill_normal(xi.data(), static_cast<std::size_t>(xi.size()), latent_noise_std());
    rep.decoder_vjp(z, xi, step);
    z += step;
    rep.decode(z, decoded);
    out.theta.bottomRows(n_low) = decoded;
    out.latent.bottomRows(n_low) = z;
    for (std::size_t i = high.size(); i < count; ++i) out.has_latent[i] = 1;
  }
  out.metrics[1] = static_cast<double>(high.size()) / static_cast<double>(count);
}

void PomsMutator::save(std::ostream& out) const {
  state::write_tag(out, "POMS");
  state::write<double>(out, threshold_);
}

void PomsMutator::load(std::istream& in) {
  state::expect_tag(in, "POMS");
  threshold_ = state::read<double>(in);
}

// ---- poms-no-jacobian -------------------------------------------------------------------------

NoJacobianMutator::NoJacobianMutator(const Config& cfg, const BuildContext&)
    : NoJacobianMutator(cfg.get_float("scale")) {}

NoJacobianMutator::NoJacobianMutator(double scale) : scale_(scale) {
  if (!(scale_ >= 0.0) || !std::isfinite(scale_)) throw ConfigError("scale", "must be finite and >= 0");
}

void NoJacobianMutator::begin_loop(const LoopContext& ctx) {
  const Representation& rep =
      latent_model(ctx.representation, "poms-no-jacobian: begin_loop needs a latent representation");
  QD_CHECK(ctx.dataset != nullptr, "poms-no-jacobian: begin_loop needs the dataset");
  const Eigen::Index ld = rep.latent_size();
  if (ctx.dataset->size() == 0) {
    latent_std_ = Vector::Zero(ld);
    return;
  }
  // As the reference (README.md): population std (ddof 0) per coordinate of the whole dataset, encoded with the
  // model trained at the end of the previous loop.
  Matrix z;
  rep.encode(Matrix(ctx.dataset->params()), z);
  const RowVector mean = z.colwise().mean();
  latent_std_ = ((z.rowwise() - mean).colwise().squaredNorm() / static_cast<double>(z.rows())).cwiseSqrt().transpose();
}

void NoJacobianMutator::mutate(const Parents& parents, std::size_t count, MutateContext& ctx, Offspring& out) {
  const Representation& rep =
      latent_model(ctx.representation, "poms-no-jacobian: needs a representation with a latent space");
  QD_CHECK(ctx.rng != nullptr, "poms-no-jacobian: mutate needs an rng");
  QD_CHECK(static_cast<std::size_t>(parents.theta.rows()) == count,
           "poms-no-jacobian: one parent per offspring expected");
  const int ld = rep.latent_size();
  QD_CHECK(latent_std_.size() == ld, "poms-no-jacobian: begin_loop must run before mutate");
  const Eigen::Index p = parents.theta.cols();
  out.reset(count, static_cast<std::size_t>(p), static_cast<std::size_t>(ld));
  out.metrics = {0.0};  // mixing ratio: the reference never mixes in parameter-space mutation
  if (count == 0) return;

  Matrix z, eps(static_cast<Eigen::Index>(count), ld), decoded;
  rep.encode(parents.theta, z);
  ctx.rng->fill_normal(eps.data(), static_cast<std::size_t>(eps.size()));
  const RowVector step_std = scale_ * latent_std_.transpose();
  z.array() += eps.array().rowwise() * step_std.array();
  rep.decode(z, decoded);
  out.theta = decoded;
  out.latent = z;
  out.has_latent.assign(count, 1);
}

void NoJacobianMutator::save(std::ostream& out) const {
  state::write_tag(out, "PMNJ");
  state::write_matrix(out, latent_std_);
}

void NoJacobianMutator::load(std::istream& in) {
  state::expect_tag(in, "PMNJ");
  Vector s;
  state::read_matrix(in, s);
  if (s.cols() != 1) throw StateError("poms-no-jacobian: malformed latent std");
  latent_std_ = std::move(s);
}

}  // namespace qd::poms
