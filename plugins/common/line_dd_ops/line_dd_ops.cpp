#include "line_dd_ops.hpp"

#include <qd/errors.hpp>

#include <numeric>
#include <string>
#include <utility>

namespace qd::line_dd {

Pairing parse_pairing(const std::string& text, const std::string& key) {
  if (text == "reference") return Pairing::kReference;
  if (text == "swap") return Pairing::kSwap;
  throw ConfigError(key, "unknown pairing \"" + text + "\" (expected reference|swap)");
}

void reference_round(std::vector<std::size_t>& y, const std::vector<std::size_t>& fixed,
                     const std::vector<std::size_t>& targets) {
  QD_CHECK(fixed.size() == targets.size(), "reference_round: one target per fixed point");
  std::vector<std::size_t> old_fixed(fixed.size()), old_targets(fixed.size());
  for (std::size_t k = 0; k < fixed.size(); ++k) {
    old_fixed[k] = y[fixed[k]];
    old_targets[k] = y[targets[k]];
  }
  for (std::size_t k = 0; k < fixed.size(); ++k) y[fixed[k]] = old_targets[k];
  for (std::size_t k = 0; k < fixed.size(); ++k) y[targets[k]] = old_fixed[k];
}

std::vector<std::size_t> derangement(std::size_t n, Rng& rng, Pairing mode) {
  std::vector<std::size_t> y(n);
  std::iota(y.begin(), y.end(), std::size_t{0});
  // Fisher-Yates from the back, as numpy's shuffle.
  for (std::size_t i = n; i > 1; --i) std::swap(y[i - 1], y[rng.below(i)]);
  if (n < 2) return y;

  std::vector<std::size_t> fixed, targets;
  for (std::size_t round = 0; round <= n; ++round) {
    fixed.clear();
    for (std::size_t i = 0; i < n; ++i)
      if (y[i] == i) fixed.push_back(i);
    if (fixed.empty()) break;
    if (mode == Pairing::kReference) {
      targets.resize(fixed.size());
      for (std::size_t k = 0; k < fixed.size(); ++k) targets[k] = (fixed[k] + 1 + rng.below(n - 1)) % n;
      reference_round(y, fixed, targets);
    } else {
      for (const std::size_t i : fixed) {
        if (y[i] != i) continue;  // an earlier swap of this round already moved it
        std::swap(y[i], y[(i + 1 + rng.below(n - 1)) % n]);
      }
    }
  }
  return y;
}

void iso_line_dd(const Matrix& theta, Eigen::Index begin, Eigen::Index n, const IsoLineParams& params, Rng& rng,
                 Matrix& out) {
  if (n <= 0) return;
  const Eigen::Index p = theta.cols();
  const auto partner = derangement(static_cast<std::size_t>(n), rng, params.pairing);
  RowVector noise(p);
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto self = theta.row(begin + i);
    const auto other = theta.row(begin + static_cast<Eigen::Index>(partner[static_cast<std::size_t>(i)]));
    rng.fill_normal(noise.data(), static_cast<std::size_t>(p), params.iso_sigma);
    const double eta = rng.normal();
    out.row(begin + i) = other + noise + (params.line_sigma * eta) * (other - self);
  }
}

void iso(const Matrix& theta, Eigen::Index begin, Eigen::Index n, double sigma, Rng& rng, Matrix& out) {
  const Eigen::Index p = theta.cols();
  RowVector noise(p);
  for (Eigen::Index i = 0; i < n; ++i) {
    rng.fill_normal(noise.data(), static_cast<std::size_t>(p), sigma);
    out.row(begin + i) = theta.row(begin + i) + noise;
  }
}

}  // namespace qd::line_dd
