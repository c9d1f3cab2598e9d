#include "dde_mutator.hpp"

#include <qd/errors.hpp>
#include <qd/state_io.hpp>

#include <cmath>
#include <limits>

namespace qd::dde {

ArmSplit split_for_arm(std::size_t arm, std::size_t count) {
  QD_CHECK(arm < kArmCount, "dde: arm out of range");
  ArmSplit s;
  // Truncation as Python's int(); the products are exact for the arms' quarter fractions.
  s.crossover = static_cast<std::size_t>(kArms[arm][0] * static_cast<double>(count));
  s.line_dd = static_cast<std::size_t>(kArms[arm][1] * static_cast<double>(count));
  s.iso = count - s.crossover - s.line_dd;
  return s;
}

DdeMutator::DdeMutator(const Config& cfg, const BuildContext&)
    : iso_sigma_(cfg.get_float("iso_sigma")),
      update_(cfg.get_string("update") == "ucb1" ? Update::kUcb1 : Update::kReference),
      count_replacements_(cfg.get_string("reward") == "insertions"),
      random_first_arm_(cfg.get_bool("random_first_arm")) {
  line_params_.iso_sigma = cfg.get_float("line_dd_iso_sigma");
  line_params_.line_sigma = cfg.get_float("line_dd_line_sigma");
  line_params_.pairing = line_dd::parse_pairing(cfg.get_string("line_dd_pairing"), "line_dd_pairing");
  values_.fill(0.0);
  counts_.fill(1);
}

std::size_t DdeMutator::ucb_arm() const {
  double total = 0.0;
  for (const auto f : counts_) total += static_cast<double>(f);
  const double log_total = std::log(total);
  std::size_t best = 0;
  double best_score = -std::numeric_limits<double>::infinity();
  for (std::size_t j = 0; j < kArmCount; ++j) {
    const double score = values_[j] + std::sqrt(2.0 * log_total / static_cast<double>(counts_[j]));
    if (score > best_score) {  // strict: the first maximum wins ties, as numpy's argmax
      best_score = score;
      best = j;
    }
  }
  return best;
}

void DdeMutator::update(std::size_t arm, double reward) {
  if (update_ == Update::kReference) {
    // As coded in the reference: the running-mean step is applied to every arm with a zero reward
    // for the unchosen ones, so their values decay by (1 − 1/f_j).
    for (std::size_t j = 0; j < kArmCount; ++j)
      values_[j] = values_[j] + ((j == arm ? reward : 0.0) - values_[j]) / static_cast<double>(counts_[j]);
    counts_[arm] += 1;
  } else {
    counts_[arm] += 1;
    values_[arm] += (reward - values_[arm]) / static_cast<double>(counts_[arm]);
  }
}

void DdeMutator::mutate(const Parents& parents, std::size_t count, MutateContext& ctx, Offspring& out) {
  QD_CHECK(ctx.rng != nullptr && ctx.representation != nullptr, "dde: no rng or representation");
  QD_CHECK(ctx.representation->latent_size() > 0, "dde: needs a representation with a latent space");
  QD_CHECK(static_cast<std::size_t>(parents.theta.rows()) == count, "dde: one parent per offspring");
  Rng& rng = *ctx.rng;

  const std::size_t arm =
      ctx.iteration == 0 && random_first_arm_ ? static_cast<std::size_t>(rng.below(kArmCount)) : ucb_arm();
  const ArmSplit split = split_for_arm(arm, count);
  const auto n_a = static_cast<Eigen::Index>(split.crossover);
  const auto n_b = static_cast<Eigen::Index>(split.line_dd);
  const auto n_c = static_cast<Eigen::Index>(split.iso);

  const int latent = ctx.representation->latent_size();
  out.reset(count, static_cast<std::size_t>(parents.theta.cols()), static_cast<std::size_t>(latent));

  // (a) deterministic: the parent averaged with its own reconstruction; its origin is z = Enc(θ).
  if (n_a > 0) {
    const Matrix block = parents.theta.topRows(n_a);
    Matrix z, reconstruction;
    ctx.representation->encode(block, z);
    ctx.representation->decode(z, reconstruction);
    out.theta.topRows(n_a) = 0.5 * (block + reconstruction);
    out.latent.topRows(n_a) = z;
    for (Eigen::Index i = 0; i < n_a; ++i) out.has_latent[static_cast<std::size_t>(i)] = 1;
  }
  // (b) paired within its own sub-batch, (c) isotropic; the core encodes both.
  line_dd::iso_line_dd(parents.theta, n_a, n_b, line_params_, rng, out.theta);
  line_dd::iso(parents.theta, n_a + n_b, n_c, iso_sigma_, rng, out.theta);

  arm_ = static_cast<int>(arm);
  pending_count_ = count;
  // The arm, and as mixing ratio arm / 9: what the reference logs in its ratio column.
  out.metrics = {static_cast<double>(arm), static_cast<double>(arm) / static_cast<double>(kArmCount)};
}

void DdeMutator::feedback(const Feedback& fb) {
  if (pending_count_ == 0 || arm_ < 0) return;  // no batch of ours is waiting
  const std::size_t inserted = fb.added + (count_replacements_ ? fb.replaced : 0);
  update(static_cast<std::size_t>(arm_), static_cast<double>(inserted) / static_cast<double>(pending_count_));
  pending_count_ = 0;
}

void DdeMutator::save(std::ostream& out) const {
  state::write_tag(out, "DDE1");
  state::write<std::uint32_t>(out, static_cast<std::uint32_t>(kArmCount));
  for (const double v : values_) state::write(out, v);
  for (const std::int64_t f : counts_) state::write(out, f);
  state::write<std::int32_t>(out, arm_);
  state::write<std::uint64_t>(out, pending_count_);
}

void DdeMutator::load(std::istream& in) {
  state::expect_tag(in, "DDE1");
  if (state::read<std::uint32_t>(in) != kArmCount) throw StateError("dde: state has a different number of arms");
  std::array<double, kArmCount> values{};
  std::array<std::int64_t, kArmCount> counts{};
  for (double& v : values) v = state::read<double>(in);
  for (std::int64_t& f : counts) {
    f = state::read<std::int64_t>(in);
    if (f < 1) throw StateError("dde: state has an arm count below 1");
  }
  const auto arm = state::read<std::int32_t>(in);
  if (arm < -1 || arm >= static_cast<std::int32_t>(kArmCount)) throw StateError("dde: state has a bad arm");
  const auto pending = state::read<std::uint64_t>(in);
  values_ = values;
  counts_ = counts;
  arm_ = arm;
  pending_count_ = pending;
}

}  // namespace qd::dde
