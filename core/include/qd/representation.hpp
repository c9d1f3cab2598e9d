// Representation: a latent model of policy parameters (none, PCA, autoencoder).
//
// Contract
//  * latent_size() == 0 means "no model": encode/decode/Jacobians must not be called, and the core
//    skips reconstruction bookkeeping.
//  * fit() is called by the core on the main thread at the end of every loop (loop 0 included)
//    with the whole dataset. It may keep state across calls (warm starts). Training randomness
//    must come from Rng(ctx.seed, Stream::kTraining, ctx.loop, ...), so resumed runs repeat it.
//  * The const members are thread-safe and may run concurrently.
//  * save()/load() round-trip the full state (weights and optimiser) bit for bit; the checkpoint
//    stores the blob. load() throws qd::StateError on a malformed or mismatched blob.
//  * What `qdrun --dry-run` asks about the cost of fit() is no part of this contract: a model whose
//    fit is costly implements qd::FitTimeEstimate (<qd/planning.hpp>) beside it.
#pragma once

#include <qd/component.hpp>
#include <qd/dataset.hpp>
#include <qd/export.hpp>
#include <qd/types.hpp>

#include <cstddef>
#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

namespace qd {

struct FitContext {
  int loop = 0;
  std::uint64_t seed = 0;  // run seed
  std::string run_dir;     // where per-epoch logs go; empty = do not log
};

struct FitReport {
  int epochs = 0;
  double train_loss = 0.0;
  double test_loss = 0.0;  // NaN when there is no test set
  bool stopped_early = false;
};

class QD_EXPORT Representation : public Component {
 public:
  ~Representation() override;

  virtual int latent_size() const noexcept = 0;

  virtual FitReport fit(const Dataset& data, const FitContext& ctx) = 0;

  // theta: N × P  ->  z: N × LD.
  virtual void encode(const Matrix& theta, Matrix& z) const = 0;
  // z: N × LD  ->  theta: N × P.
  virtual void decode(const Matrix& z, Matrix& theta) const = 0;
  // jacobians[i] = ∂Dec/∂z at z.row(i), a P × LD matrix.
  virtual void decoder_jacobians(const Matrix& z, std::vector<Matrix>& jacobians) const = 0;
  // out.row(i) = (J(z_i)ᵀ v_iᵀ)ᵀ: the vector-Jacobian product, N × LD. The default builds the
  // Jacobians; models with a closed form override it (PoMS's latent noise is exactly this).
  virtual void decoder_vjp(const Matrix& z, const Matrix& v, Matrix& out) const;
  // errors[i] = ‖θ_i − Dec(Enc(θ_i))‖₂.
  virtual void reconstruction_errors(const Matrix& theta, Vector& errors) const;

  // Files this representation appends to in FitContext::run_dir (e.g. per-epoch losses). The core
  // records their sizes at every checkpoint and cuts them back when a run resumes; every write to
  // them must be checked (a failed write throws), so a log is complete or the run fails.
  virtual std::vector<std::string> log_files() const;

  virtual void save(std::ostream& out) const = 0;
  virtual void load(std::istream& in) = 0;
};

}  // namespace qd
