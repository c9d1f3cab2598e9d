// The policy network: an MLP with tanh hidden layers and a linear output (docs/design.md).
//
// Flat parameter layout θ ∈ R^P, exactly the reference's: for each layer l in order, a matrix of
// (n_in + 1) rows × n_out columns flattened row-major (index r * n_out + c); rows 0..n_in-1 hold
// the weights from input r to each output, the last row is the bias. The layer computes
// y = x · K + b. For obs 14, hidden [32, 32], act 3 this gives P = 15*32 + 33*32 + 33*3 = 1635.
// Inference runs in float32, as the reference does.
#pragma once

#include <qd/export.hpp>

#include <Eigen/Core>

#include <cstddef>
#include <vector>

namespace qd {

class QD_EXPORT PolicyShape {
 public:
  PolicyShape() = default;
  PolicyShape(int inputs, std::vector<int> hidden, int outputs);
  // A plain vector of `parameters` values and no network, for environments that evaluate parameter
  // vectors directly (EnvironmentInfo::parameters): layers() is 0, inputs() and outputs() are 0.
  static PolicyShape direct(std::size_t parameters);
  bool is_direct() const noexcept { return sizes_.empty() && !offsets_.empty(); }

  int inputs() const noexcept { return sizes_.empty() ? 0 : sizes_.front(); }
  int outputs() const noexcept { return sizes_.empty() ? 0 : sizes_.back(); }
  const std::vector<int>& hidden() const noexcept { return hidden_; }
  int layers() const noexcept { return sizes_.empty() ? 0 : static_cast<int>(sizes_.size()) - 1; }
  int layer_inputs(int l) const noexcept { return sizes_[static_cast<std::size_t>(l)]; }
  int layer_outputs(int l) const noexcept { return sizes_[static_cast<std::size_t>(l) + 1]; }
  // Offset of layer l's (n_in + 1) × n_out block in θ.
  std::size_t layer_offset(int l) const noexcept { return offsets_[static_cast<std::size_t>(l)]; }
  std::size_t param_count() const noexcept { return offsets_.empty() ? 0 : offsets_.back(); }

 private:
  std::vector<int> hidden_;
  std::vector<int> sizes_;            // inputs, hidden..., outputs
  std::vector<std::size_t> offsets_;  // layers + 1 entries; last = P
};

// One policy loaded for inference. Not thread-safe; make one per worker (cheap). A direct shape has
// no network to load.
class QD_EXPORT Policy {
 public:
  explicit Policy(const PolicyShape& shape);

  // Loads parameters θ (param_count() doubles, the flat layout above), converting to float.
  void load(const double* theta);
  // Computes the action for `observation` (inputs() floats). Returns a pointer to outputs() floats
  // owned by this object, valid until the next call.
  const float* act(const float* observation);

  const PolicyShape& shape() const noexcept { return shape_; }

 private:
  using MatrixF = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic>;
  PolicyShape shape_;
  std::vector<MatrixF> weights_t_;  // layer l: n_out × n_in (transposed kernel, column-major)
  std::vector<Eigen::VectorXf> biases_;
  std::vector<Eigen::VectorXf> activations_;
};

}  // namespace qd
