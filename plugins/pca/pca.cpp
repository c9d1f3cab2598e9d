#include "pca.hpp"

#include <qd/errors.hpp>
#include <qd/rng.hpp>
#include <qd/state_io.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <mutex>
#include <sstream>
#include <string>
#include <tuple>

namespace qd::pca {

const ParamSpec kParams[1] = {
    param_int("latent", "50", 1, kUnbounded,
              "number of principal components LD (the latent size); must not exceed the policy's parameter count"),
};

namespace {

// Makes the rows of w[0, rows) orthonormal (modified Gram-Schmidt, applied twice: "twice is
// enough" for full working accuracy even when the input rows are only nearly orthogonal).
void orthonormalise_rows(Matrix& w, Eigen::Index rows) {
  for (int pass = 0; pass < 2; ++pass) {
    for (Eigen::Index r = 0; r < rows; ++r) {
      for (Eigen::Index q = 0; q < r; ++q) w.row(r) -= w.row(q).dot(w.row(r)) * w.row(q);
      w.row(r) /= w.row(r).norm();
    }
  }
}

// Fills rows [from, LD) with unit vectors orthogonal to the rows before them. Used where the data
// has fewer than LD directions of non-zero variance: any orthonormal completion is a valid PCA
// answer there, so pick one from the standard basis (greedily, the basis vector with the largest
// residual) that does not depend on the eigen-solver's internals.
void complete_basis(Matrix& w, Eigen::Index from) {
  const Eigen::Index p = w.cols();
  Vector captured = w.topRows(from).colwise().squaredNorm().transpose();  // ‖projection of e_i‖²
  for (Eigen::Index r = from; r < w.rows(); ++r) {
    Eigen::Index best = 0;
    double best_residual = -1.0;
    for (Eigen::Index i = 0; i < p; ++i) {
      if (1.0 - captured(i) > best_residual + 1e-12) {
        best_residual = 1.0 - captured(i);
        best = i;
      }
    }
    w.row(r).setZero();
    w(r, best) = 1.0;
    for (int pass = 0; pass < 2; ++pass) {
      for (Eigen::Index q = 0; q < r; ++q) w.row(r) -= w.row(q).dot(w.row(r)) * w.row(q);
    }
    w.row(r) /= w.row(r).norm();
    captured += w.row(r).array().square().matrix().transpose();
  }
}

// Deterministic sign: the largest-magnitude entry of each component is positive (first one on ties).
void fix_signs(Matrix& w) {
  for (Eigen::Index r = 0; r < w.rows(); ++r) {
    Eigen::Index arg = 0;
    w.row(r).cwiseAbs().maxCoeff(&arg);
    if (w(r, arg) < 0.0) w.row(r) *= -1.0;
  }
}

}  // namespace

PcaRepresentation::PcaRepresentation(const Config& cfg, const BuildContext& ctx)
    : latent_(static_cast<int>(cfg.get_int("latent"))), params_(0) {
  if (ctx.policy == nullptr) throw Error("pca: the policy shape is unknown when the representation is built");
  params_ = ctx.policy->param_count();
  if (static_cast<std::size_t>(latent_) > params_) {
    throw ConfigError("latent", "latent = " + std::to_string(latent_) + " exceeds the policy's parameter count " +
                                    std::to_string(params_) + " (PCA has at most that many components)");
  }
  reset_unfitted();
}

PcaRepresentation::PcaRepresentation(int latent, std::size_t params) : latent_(latent), params_(params) {
  if (latent_ < 1 || static_cast<std::size_t>(latent_) > params_)
    throw ConfigError("latent", "latent must be in [1, " + std::to_string(params_) + "]");
  reset_unfitted();
}

void PcaRepresentation::reset_unfitted() {
  // Before the first fit: the first LD coordinate axes around 0, so that the model is usable.
  components_ = Matrix::Zero(latent_, static_cast<Eigen::Index>(params_));
  complete_basis(components_, 0);
  mean_ = RowVector::Zero(static_cast<Eigen::Index>(params_));
  explained_variance_ = Vector::Zero(latent_);
  explained_variance_ratio_ = Vector::Zero(latent_);
  tiled_ = false;
}

void PcaRepresentation::fit_matrix(const Matrix& data) {
  const Eigen::Index n = data.rows();
  const Eigen::Index p = static_cast<Eigen::Index>(params_);
  if (n == 0) throw Error("pca: cannot fit an empty dataset");
  QD_CHECK(data.cols() == p, "pca: data has the wrong number of columns");

  mean_ = data.colwise().mean();
  const Matrix centred = data.rowwise() - mean_;

  // Reference rule (README.md): with fewer samples than components the data are tiled LD times
  // before fitting. Tiling k times multiplies the Gram/scatter matrix by k and leaves the mean,
  // the components and the variance ratios unchanged; only the ddof-1 variance changes, to
  // k·s²/(k·N − 1). So it is applied in closed form instead of copying the data.
  tiled_ = n < latent_;
  const double tiles = tiled_ ? static_cast<double>(latent_) : 1.0;
  const double samples = tiles * static_cast<double>(n);

  // Exact eigen-decomposition of the smaller of the Gram (N × N) and scatter (P × P) matrices.
  const bool use_gram = n <= p;
  Eigen::MatrixXd scatter;
  if (use_gram) {
    scatter.noalias() = centred * centred.transpose();
  } else {
    scatter.noalias() = centred.transpose() * centred;
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(scatter);
  if (solver.info() != Eigen::Success) throw Error("pca: the eigen-decomposition did not converge");
  const Eigen::VectorXd& values = solver.eigenvalues();  // ascending
  const Eigen::MatrixXd& vectors = solver.eigenvectors();

  const double largest = std::max(values(values.size() - 1), 0.0);
  // Below this an eigenvalue is round-off: its direction is arbitrary, so it is replaced below.
  const double noise_floor =
      largest * static_cast<double>(scatter.rows()) * std::numeric_limits<double>::epsilon() * 16.0;

  components_.setZero(latent_, p);
  Vector variance = Vector::Zero(latent_);
  Eigen::Index found = 0;
  for (Eigen::Index j = values.size() - 1; j >= 0 && found < latent_; --j) {
    const double lambda = values(j);
    if (!(lambda > noise_floor)) break;
    if (use_gram) {
      components_.row(found) = (centred.transpose() * vectors.col(j)).transpose() / std::sqrt(lambda);
    } else {
      components_.row(found) = vectors.col(j).transpose();
    }
    variance(found) = lambda;
    ++found;
  }
  orthonormalise_rows(components_, found);
  complete_basis(components_, found);
  fix_signs(components_);

  const double total = centred.squaredNorm();
  explained_variance_ = samples > 1.0 ? Vector(variance * (tiles / (samples - 1.0))) : Vector::Zero(latent_);
  explained_variance_ratio_ = total > 0.0 ? Vector(variance / total) : Vector::Zero(latent_);
}

std::vector<double> PcaRepresentation::estimate_fit_seconds(const std::vector<std::size_t>& rows) const {
  std::vector<double> seconds(rows.size(), 0.0);
  if (rows.empty()) return seconds;
  const auto P = static_cast<Eigen::Index>(params_);
  auto time_fit = [&](std::size_t n) {
    PcaRepresentation probe(latent_, params_);
    Rng rng(0, Stream::kTraining, 0);
    Matrix data(static_cast<Eigen::Index>(n), P);
    for (Eigen::Index r = 0; r < data.rows(); ++r)
      for (Eigen::Index c = 0; c < P; ++c) data(r, c) = rng.uniform(-1.0, 1.0);
    const auto start = std::chrono::steady_clock::now();
    probe.fit_matrix(data);
    Vector errors;
    probe.reconstruction_errors(data, errors);  // fit() computes the training loss too
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  const std::size_t lo = std::max<std::size_t>(1, *std::min_element(rows.begin(), rows.end()));
  const std::size_t hi = std::max(lo, *std::max_element(rows.begin(), rows.end()));
  // A sweep asks once per run, mostly about the same sizes: each is timed once per process.
  static std::mutex cache_mutex;
  static std::map<std::tuple<std::size_t, int, std::size_t>, double> cache;
  auto timed = [&](std::size_t n) {
    const std::lock_guard<std::mutex> lock(cache_mutex);
    const auto key = std::make_tuple(params_, latent_, n);
    auto it = cache.find(key);
    if (it == cache.end()) it = cache.emplace(key, time_fit(n)).first;
    return it->second;
  };
  const double t_lo = timed(lo), t_hi = hi == lo ? t_lo : timed(hi);
  const double exponent =
      hi == lo || t_lo <= 0 || t_hi <= 0 ? 1.0 : std::log(t_hi / t_lo) / std::log(static_cast<double>(hi) / lo);
  for (std::size_t l = 0; l < rows.size(); ++l)
    seconds[l] = rows[l] == 0 ? 0.0 : t_lo * std::pow(static_cast<double>(rows[l]) / static_cast<double>(lo), exponent);
  return seconds;
}

FitReport PcaRepresentation::fit(const Dataset& data, const FitContext& ctx) {
  const Matrix params = data.params();
  fit_matrix(params);

  FitReport report;
  report.epochs = 0;
  // Same loss as the autoencoder's (mean over samples of the per-sample SSE), for comparison.
  Vector errors;
  reconstruction_errors(params, errors);
  report.train_loss = errors.squaredNorm() / static_cast<double>(errors.size());
  report.test_loss = std::numeric_limits<double>::quiet_NaN();

  if (ctx.log) {
    std::ostringstream out;
    out.precision(std::numeric_limits<double>::max_digits10);
    for (int k = 0; k < latent_; ++k) out << ctx.loop << ',' << k << ',' << explained_variance_ratio_(k) << '\n';
    ctx.log->append("pca.csv", "loop,component,explained_variance_ratio\n", out.str());
  }
  return report;
}

void PcaRepresentation::encode(const Matrix& theta, Matrix& z) const {
  QD_CHECK(theta.cols() == static_cast<Eigen::Index>(params_), "pca: encode input has the wrong width");
  z.noalias() = (theta.rowwise() - mean_) * components_.transpose();
}

void PcaRepresentation::decode(const Matrix& z, Matrix& theta) const {
  QD_CHECK(z.cols() == latent_, "pca: decode input has the wrong width");
  theta.noalias() = z * components_;
  theta.rowwise() += mean_;
}

void PcaRepresentation::decoder_jacobians(const Matrix& z, std::vector<Matrix>& jacobians) const {
  QD_CHECK(z.cols() == latent_, "pca: decoder_jacobians input has the wrong width");
  jacobians.assign(static_cast<std::size_t>(z.rows()), components_.transpose());
}

void PcaRepresentation::decoder_vjp(const Matrix& z, const Matrix& v, Matrix& out) const {
  QD_CHECK(z.rows() == v.rows(), "pca: decoder_vjp needs as many vectors as latent points");
  QD_CHECK(v.cols() == static_cast<Eigen::Index>(params_), "pca: decoder_vjp vectors have the wrong width");
  // Row form of Jᵀv with J = Wᵀ: vᵀ Wᵀ.
  out.noalias() = v * components_.transpose();
}

void PcaRepresentation::save(std::ostream& out) const {
  state::write_tag(out, "PCA1");
  state::write<std::int32_t>(out, latent_);
  state::write<std::uint64_t>(out, params_);
  state::write_matrix(out, components_);
  state::write_matrix(out, mean_);
  state::write_matrix(out, explained_variance_);
  state::write_matrix(out, explained_variance_ratio_);
  state::write<std::uint8_t>(out, tiled_ ? 1 : 0);
}

void PcaRepresentation::load(std::istream& in) {
  state::expect_tag(in, "PCA1");
  const auto latent = state::read<std::int32_t>(in);
  const auto params = state::read<std::uint64_t>(in);
  if (latent != latent_ || params != params_)
    throw StateError("pca: state blob is for latent " + std::to_string(latent) + ", " + std::to_string(params) +
                     " parameters; this model has latent " + std::to_string(latent_) + ", " + std::to_string(params_));
  Matrix components;
  RowVector mean;
  Vector variance, ratio;
  state::read_matrix(in, components);
  state::read_matrix(in, mean);
  state::read_matrix(in, variance);
  state::read_matrix(in, ratio);
  const auto tiled = state::read<std::uint8_t>(in);
  const auto p = static_cast<Eigen::Index>(params_);
  if (components.rows() != latent_ || components.cols() != p || mean.cols() != p || variance.size() != latent_ ||
      ratio.size() != latent_ || tiled > 1)
    throw StateError("pca: state blob has inconsistent shapes");
  components_ = std::move(components);
  mean_ = std::move(mean);
  explained_variance_ = std::move(variance);
  explained_variance_ratio_ = std::move(ratio);
  tiled_ = tiled == 1;
}

}  // namespace qd::pca
