#include "cma_es.hpp"

#include <qd/errors.hpp>
#include <qd/state_io.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <vector>

namespace qd::cma_me {

namespace {

struct Strategy {
  Vector weights;
  double mueff, cc, cs, c1, cmu, damps;
};

// Weights and learning rates for `mu` parents in dimension n.
Strategy strategy(std::size_t n, std::size_t mu) {
  Strategy s;
  s.weights.resize(static_cast<Eigen::Index>(mu));
  for (std::size_t i = 0; i < mu; ++i)
    s.weights[static_cast<Eigen::Index>(i)] =
        std::log(static_cast<double>(mu) + 0.5) - std::log(static_cast<double>(i + 1));
  s.weights /= s.weights.sum();
  s.mueff = 1.0 / s.weights.squaredNorm();
  const double d = static_cast<double>(n);
  s.cc = (4.0 + s.mueff / d) / (d + 4.0 + 2.0 * s.mueff / d);
  s.cs = (s.mueff + 2.0) / (d + s.mueff + 5.0);
  s.c1 = 2.0 / ((d + 1.3) * (d + 1.3) + s.mueff);
  s.cmu = std::min(1.0 - s.c1, 2.0 * (s.mueff - 2.0 + 1.0 / s.mueff) / ((d + 2.0) * (d + 2.0) + s.mueff));
  s.damps = 1.0 + 2.0 * std::max(0.0, std::sqrt((s.mueff - 1.0) / (d + 1.0)) - 1.0) + s.cs;
  return s;
}

}  // namespace

CmaEs::CmaEs(std::size_t n, std::size_t lambda, double sigma0) : n_(n), lambda_(lambda), sigma0_(sigma0) {
  QD_CHECK(n >= 1 && lambda >= 2 && sigma0 > 0.0, "CMA-ES needs n >= 1, lambda >= 2 and sigma0 > 0");
  const Strategy s = strategy(n, lambda / 2);
  lazy_gap_ = 0.5 * static_cast<double>(n) * static_cast<double>(lambda) / (s.c1 + s.cmu) /
              (static_cast<double>(n) * static_cast<double>(n));
  const Vector zero = Vector::Zero(static_cast<Eigen::Index>(n));
  reset(zero.data());
}

void CmaEs::reset(const double* mean) {
  const auto n = static_cast<Eigen::Index>(n_);
  mean_ = Eigen::Map<const Vector>(mean, n);
  sigma_ = sigma0_;
  pc_.setZero(n);
  ps_.setZero(n);
  c_.setIdentity(n, n);
  transform_.setIdentity(n, n);
  invsqrt_.setIdentity(n, n);
  eigenvalues_.setOnes(n);
  evaluations_ = eigen_evaluations_ = 0;
}

void CmaEs::update_eigensystem() {
  if (static_cast<double>(evaluations_) <= static_cast<double>(eigen_evaluations_) + lazy_gap_) return;
  const Matrix sym = c_.cwiseMax(c_.transpose());  // as pyribs: symmetric by construction
  c_ = sym;
  const Eigen::SelfAdjointEigenSolver<Matrix> eig(sym);
  eigenvalues_ = eig.eigenvalues().cwiseAbs();
  const Matrix& b = eig.eigenvectors();
  // IEEE square roots: Eigen's vectorised sqrt is rsqrt14 plus Newton steps on AVX-512, an
  // approximation whose last bits are the CPU's, not the standard's (tests/golden/exact_arithmetic.sh).
  const Vector root = eigenvalues_.unaryExpr([](double x) { return std::sqrt(x); });
  transform_ = b * root.asDiagonal();
  invsqrt_ = b * root.cwiseInverse().asDiagonal() * b.transpose();
  eigen_evaluations_ = evaluations_;
}

void CmaEs::sample(Rng& rng, double* out) {
  update_eigensystem();
  const auto n = static_cast<Eigen::Index>(n_);
  Vector z(n);
  for (std::size_t k = 0; k < lambda_; ++k) {
    rng.fill_normal(z.data(), n_);
    Eigen::Map<Vector> x(out + k * n_, n);
    x.noalias() = mean_ + sigma_ * (transform_ * z);
  }
}

void CmaEs::tell(const Matrix& parents) {
  const auto mu = static_cast<std::size_t>(parents.rows());
  QD_CHECK(mu >= 1 && parents.cols() == static_cast<Eigen::Index>(n_), "CMA-ES: tell() needs 1 or more parents");
  evaluations_ += lambda_;
  const Strategy s = strategy(n_, mu);
  const double n = static_cast<double>(n_);

  const Vector old_mean = mean_;
  mean_ = parents.transpose() * s.weights;
  const Vector step = (mean_ - old_mean) / sigma_;
  ps_ = (1.0 - s.cs) * ps_ + std::sqrt(s.cs * (2.0 - s.cs) * s.mueff) * (invsqrt_ * step);
  const double generations = static_cast<double>(evaluations_) / static_cast<double>(lambda_);
  const double left = ps_.squaredNorm() / n / (1.0 - std::pow(1.0 - s.cs, 2.0 * generations));
  const double hsig = left < 2.0 + 4.0 / (n + 1.0) ? 1.0 : 0.0;
  pc_ = (1.0 - s.cc) * pc_ + hsig * std::sqrt(s.cc * (2.0 - s.cc) * s.mueff) * step;

  Matrix y = parents.rowwise() - old_mean.transpose();  // mu x n
  y /= sigma_;
  const Matrix weighted = s.weights.asDiagonal() * y;
  const double decay = 1.0 - s.c1 - s.cmu + (1.0 - hsig) * s.c1 * s.cc * (2.0 - s.cc);
  c_ = decay * c_ + s.c1 * (pc_ * pc_.transpose()) + s.cmu * (weighted.transpose() * y);

  sigma_ *= std::exp(std::min(1.0, s.cs / s.damps * (ps_.squaredNorm() / n - 1.0) / 2.0));
}

bool CmaEs::converged() const {
  const double largest = eigenvalues_.maxCoeff(), smallest = eigenvalues_.minCoeff();
  if (!(smallest > 0.0) || largest / smallest > 1e14) return true;
  return sigma_ * std::sqrt(largest) < 1e-11;
}

void CmaEs::save(std::ostream& out) const {
  state::write_tag(out, "CMAE");
  state::write<std::uint64_t>(out, n_);
  state::write<std::uint64_t>(out, lambda_);
  state::write(out, sigma_);
  state::write(out, evaluations_);
  state::write(out, eigen_evaluations_);
  for (const Vector* v : {&mean_, &pc_, &ps_, &eigenvalues_}) state::write_matrix(out, *v);
  for (const Matrix* m : {&c_, &transform_, &invsqrt_}) state::write_matrix(out, *m);
}

void CmaEs::load(std::istream& in) {
  state::expect_tag(in, "CMAE");
  if (state::read<std::uint64_t>(in) != n_ || state::read<std::uint64_t>(in) != lambda_)
    throw StateError("CMA-ES state of another dimension or population size");
  sigma_ = state::read<double>(in);
  evaluations_ = state::read<std::uint64_t>(in);
  eigen_evaluations_ = state::read<std::uint64_t>(in);
  const auto n = static_cast<Eigen::Index>(n_);
  for (Vector* v : {&mean_, &pc_, &ps_, &eigenvalues_}) {
    state::read_matrix(in, *v);
    if (v->size() != n) throw StateError("CMA-ES state has a vector of the wrong size");
  }
  for (Matrix* m : {&c_, &transform_, &invsqrt_}) {
    state::read_matrix(in, *m);
    if (m->rows() != n || m->cols() != n) throw StateError("CMA-ES state has a matrix of the wrong size");
  }
}

}  // namespace qd::cma_me
