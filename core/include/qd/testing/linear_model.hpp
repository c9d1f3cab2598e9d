// A linear latent model, for testing mutators (and anything else that needs a Representation)
// without training one. Header-only: it is compiled into the test that uses it.
//
// Dec(z) = z·W + μ, Enc(θ) = (θ − μ)·Wᵀ, ∂Dec/∂z = Wᵀ for every z, with W an LD × P matrix.
// When the rows of W are orthonormal (random() makes them so) Enc inverts Dec, and the model
// behaves like PCA. fit() leaves the model as it is; save()/load() round-trip W and μ.
#pragma once

#include <qd/representation.hpp>
#include <qd/rng.hpp>
#include <qd/state_io.hpp>
#include <qd/types.hpp>

#include <Eigen/QR>

#include <cstdint>
#include <istream>
#include <memory>
#include <ostream>
#include <utility>
#include <vector>

namespace qd::testing {

class LinearModel final : public Representation {
 public:
  LinearModel(Matrix w, RowVector mu) : w_(std::move(w)), mu_(std::move(mu)) {}

  // LD orthonormal rows in R^P (a random rotation's first rows) and a mean with entries U(-1, 1).
  static std::unique_ptr<LinearModel> random(int latent, int params, std::uint64_t seed) {
    Rng rng(seed, Stream::kPlugin, 0x6c696e /* "lin" */);
    Eigen::MatrixXd g(params, latent);
    rng.fill_normal(g.data(), static_cast<std::size_t>(g.size()));
    const Eigen::MatrixXd q =
        Eigen::HouseholderQR<Eigen::MatrixXd>(g).householderQ() * Eigen::MatrixXd::Identity(params, latent);
    RowVector mu(params);
    rng.fill_uniform(mu.data(), static_cast<std::size_t>(params), -1.0, 1.0);
    return std::make_unique<LinearModel>(Matrix(q.transpose()), std::move(mu));
  }

  const Matrix& weights() const noexcept { return w_; }
  const RowVector& mean() const noexcept { return mu_; }

  int latent_size() const noexcept override { return static_cast<int>(w_.rows()); }
  FitReport fit(const Dataset&, const FitContext&) override { return {}; }
  void encode(const Matrix& theta, Matrix& z) const override { z = (theta.rowwise() - mu_) * w_.transpose(); }
  void decode(const Matrix& z, Matrix& theta) const override { theta = (z * w_).rowwise() + mu_; }
  void decoder_jacobians(const Matrix& z, std::vector<Matrix>& jacobians) const override {
    jacobians.assign(static_cast<std::size_t>(z.rows()), w_.transpose());
  }
  void decoder_vjp(const Matrix&, const Matrix& v, Matrix& out) const override { out = v * w_.transpose(); }
  void save(std::ostream& out) const override {
    state::write_tag(out, "LINM");
    state::write_matrix(out, w_);
    state::write_matrix(out, mu_);
  }
  void load(std::istream& in) override {
    state::expect_tag(in, "LINM");
    state::read_matrix(in, w_);
    state::read_matrix(in, mu_);
  }

 private:
  Matrix w_;
  RowVector mu_;
};

}  // namespace qd::testing
