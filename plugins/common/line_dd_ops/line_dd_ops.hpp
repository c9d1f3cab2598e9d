// Iso+LineDD (Vassiliades & Mouret, GECCO 2018) and the reference's partner pairing (README.md).
//
// Shared by the line_dd and dde plugins through the static library qd_line_dd_ops (linked into
// each plugin, so neither needs the other built or loaded).
#pragma once

#include <qd/rng.hpp>
#include <qd/types.hpp>

#include <cstddef>
#include <string>
#include <vector>

namespace qd::line_dd {

enum class Pairing {
  // The reference's vectorised fix-up: all fixed points of a round are handled at once with numpy
  // fancy-index assignment. When two fixed points draw the same target (or one targets another
  // fixed point) a partner is duplicated and another dropped, so the result is then not a
  // permutation (it never has fixed points).
  kReference,
  // Each fixed point is swapped in turn (skipped if an earlier swap already moved it): always a
  // permutation, and one round always suffices.
  kSwap,
};

// Parses "reference" | "swap"; throws qd::ConfigError(key, ...) otherwise.
Pairing parse_pairing(const std::string& text, const std::string& key);

// One reference fix-up round, with the drawn targets given: tmp = y[fixed]; y[fixed] = y[targets];
// y[targets] = tmp, element-wise in order (later writes win, as numpy's do).
void reference_round(std::vector<std::size_t>& y, const std::vector<std::size_t>& fixed,
                     const std::vector<std::size_t>& targets);

// partner[i] = π(i) for a batch of n: a random permutation (Fisher-Yates), then, while fixed points
// remain, each fixed point i moves to (i + U{1, n-1}) mod n; gives up after n + 1 rounds.
// n = 1 has no derangement: the single parent is its own partner.
std::vector<std::size_t> derangement(std::size_t n, Rng& rng, Pairing mode);

struct IsoLineParams {
  double iso_sigma = 0.01;
  double line_sigma = 0.2;
  Pairing pairing = Pairing::kReference;
};

// Rows [begin, begin + n) of `out` from rows [begin, begin + n) of `theta`, pairing within that
// block: θ′_i = θ_π(i) + iso_sigma·ε_P + line_sigma·η·(θ_π(i) − θ_i), η ~ N(0, 1) per offspring.
// Draw order (reference): the pairing, then per offspring ε (P normals) followed by η.
void iso_line_dd(const Matrix& theta, Eigen::Index begin, Eigen::Index n, const IsoLineParams& params, Rng& rng,
                 Matrix& out);

// Rows [begin, begin + n): θ′ = θ + sigma·ε_P (MAPE-Iso).
void iso(const Matrix& theta, Eigen::Index begin, Eigen::Index n, double sigma, Rng& rng, Matrix& out);

}  // namespace qd::line_dd
