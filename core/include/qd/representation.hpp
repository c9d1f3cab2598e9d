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

// Where fit() may log its training (per-epoch losses, explained variance): the core appends the
// rows to a file of the run directory, records its size at every checkpoint and cuts it back when
// a run resumes, so the log always matches the model the run continues from.
class TrainingLog {
 public:
  // Appends `rows` (whole lines, possibly none) to the run's log `name`, a plain file name ending
  // in ".csv" that is not one of the core's ("losses.csv"), writing `header` first when the log
  // is new. Throws when the write fails: a full disk fails the run, it never drops rows.
  virtual void append(const std::string& name, const std::string& header, const std::string& rows) = 0;

 protected:
  virtual ~TrainingLog() = default;
};

struct FitContext {
  int loop = 0;
  std::uint64_t seed = 0;      // run seed
  TrainingLog* log = nullptr;  // null: do not log (the dry-run's pilot, tests)
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

  virtual void save(std::ostream& out) const = 0;
  virtual void load(std::istream& in) = 0;
};

}  // namespace qd
