// PCA representation (README.md): exact principal components of the dataset, refitted from
// scratch every loop. Enc(θ) = (θ − μ)Wᵀ, Dec(z) = zW + μ, ∂Dec/∂z = Wᵀ (constant).
#pragma once

#include <qd/config.hpp>
#include <qd/planning.hpp>
#include <qd/representation.hpp>

#include <cstddef>
#include <iosfwd>

namespace qd::pca {

extern const ParamSpec kParams[1];

class PcaRepresentation final : public Representation, public FitTimeEstimate {
 public:
  PcaRepresentation(const Config& cfg, const BuildContext& ctx);
  // Direct construction (tests): `latent` components of `params`-dimensional vectors.
  PcaRepresentation(int latent, std::size_t params);

  int latent_size() const noexcept override { return latent_; }
  FitReport fit(const Dataset& data, const FitContext& ctx) override;

  void encode(const Matrix& theta, Matrix& z) const override;
  void decode(const Matrix& z, Matrix& theta) const override;
  void decoder_jacobians(const Matrix& z, std::vector<Matrix>& jacobians) const override;
  void decoder_vjp(const Matrix& z, const Matrix& v, Matrix& out) const override;

  // Times fits of a fresh model on random data at the smallest and the largest row count and
  // interpolates a power law in the rows between them.
  std::vector<double> estimate_fit_seconds(const std::vector<std::size_t>& rows) const override;
  void save(std::ostream& out) const override;
  void load(std::istream& in) override;

  // Fits on a plain N × P matrix (fit() passes the dataset's parameters).
  void fit_matrix(const Matrix& data);

  // LD × P, orthonormal rows, in decreasing order of explained variance.
  const Matrix& components() const noexcept { return components_; }
  const RowVector& mean() const noexcept { return mean_; }
  // Per component: variance along it (ddof 1, of the tiled data when tiling applied) and its
  // share of the total variance.
  const Vector& explained_variance() const noexcept { return explained_variance_; }
  const Vector& explained_variance_ratio() const noexcept { return explained_variance_ratio_; }
  // Whether the last fit used the reference tiling rule (N < LD).
  bool tiled() const noexcept { return tiled_; }

 private:
  void reset_unfitted();

  int latent_;
  std::size_t params_;
  Matrix components_;
  RowVector mean_;
  Vector explained_variance_;
  Vector explained_variance_ratio_;
  bool tiled_ = false;
};

}  // namespace qd::pca
