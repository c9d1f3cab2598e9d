// CMA-ES (Hansen & Ostermeier 2001; Hansen, "The CMA Evolution Strategy: A Tutorial", 2016) as
// CMA-ME's emitters use it: the caller samples a generation, ranks it by its own criterion and
// hands back the best `mu` samples, best first; mu may change from one generation to the next (the
// weights, mu_eff and learning rates are recomputed for it, as in the CMA-ME paper's code and
// pyribs). The eigendecomposition of C is refreshed lazily, every
// 0.5 n lambda / (c1 + c_mu) / n^2 evaluations (c1, c_mu for mu = lambda / 2), as pyribs does.
//
// Sampling: x = m + sigma B diag(sqrt(eigenvalues)) z, z ~ N(0, I) from the caller's qd::Rng.
// Update (weights w_i ∝ ln(mu + 1/2) - ln i, summing to 1; y_i = (x_i - m) / sigma):
//   m'  = sum w_i x_i
//   p_s = (1 - c_s) p_s + sqrt(c_s (2 - c_s) mu_eff) C^-1/2 (m' - m) / sigma
//   h_s = |p_s|^2 / n / (1 - (1 - c_s)^(2 evaluations / lambda)) < 2 + 4 / (n + 1)
//   p_c = (1 - c_c) p_c + h_s sqrt(c_c (2 - c_c) mu_eff) (m' - m) / sigma
//   C   = (1 - c1 - c_mu + (1 - h_s) c1 c_c (2 - c_c)) C + c1 p_c p_c^T + c_mu sum w_i y_i y_i^T
//   sigma *= exp(min(1, c_s / d_s (|p_s|^2 / n - 1) / 2))
// with c_c = (4 + mu_eff / n) / (n + 4 + 2 mu_eff / n), c_s = (mu_eff + 2) / (n + mu_eff + 5),
// c1 = 2 / ((n + 1.3)^2 + mu_eff), c_mu = min(1 - c1, 2 (mu_eff - 2 + 1 / mu_eff) / ((n + 2)^2 + mu_eff)),
// d_s = 1 + 2 max(0, sqrt((mu_eff - 1) / (n + 1)) - 1) + c_s.
#pragma once

#include <qd/rng.hpp>
#include <qd/types.hpp>

#include <cstddef>
#include <cstdint>
#include <iosfwd>

namespace qd::cma_me {

class CmaEs {
 public:
  CmaEs(std::size_t n, std::size_t lambda, double sigma0);

  // A fresh start at `mean`: sigma = sigma0, C = I, no evolution paths.
  void reset(const double* mean);
  // Writes `lambda` samples into consecutive rows of `out` (row stride n).
  void sample(Rng& rng, double* out);
  // The update from the best `mu` samples of the generation just sampled (rows of `parents`, best
  // first; mu >= 1). Counts lambda evaluations.
  void tell(const Matrix& parents);
  // Counts a generation that gave no parents (no update, as pyribs does).
  void skip() { evaluations_ += lambda_; }
  // pycma's stop criteria: the condition number of C above 1e14, or sigma sqrt(max eigenvalue)
  // below 1e-11.
  bool converged() const;

  std::size_t dimension() const noexcept { return n_; }
  std::size_t lambda() const noexcept { return lambda_; }
  double sigma() const noexcept { return sigma_; }
  const Vector& mean() const noexcept { return mean_; }
  const Matrix& covariance() const noexcept { return c_; }
  std::uint64_t evaluations() const noexcept { return evaluations_; }

  // The whole state, bit for bit.
  void save(std::ostream& out) const;
  void load(std::istream& in);

 private:
  void update_eigensystem();

  std::size_t n_, lambda_;
  double sigma0_, lazy_gap_;
  double sigma_ = 0.0;
  Vector mean_, pc_, ps_;
  Matrix c_;          // covariance
  Matrix transform_;  // B diag(sqrt(eigenvalues)): z -> x - m, in units of sigma
  Matrix invsqrt_;    // C^-1/2
  Vector eigenvalues_;
  std::uint64_t evaluations_ = 0, eigen_evaluations_ = 0;  // since reset; at the last eigendecomposition
};

}  // namespace qd::cma_me
