// The PoMS parameter autoencoder (README.md): P -> HD (ELU) -> LD -> HD (ELU) -> P, trained with
// Adam on the per-sample sum of squared errors, with the reference's train/test split and
// slope-based early stopping. The model is a template on its scalar (float32 or float64); the
// qd::Representation wrapper converts at the interface, where everything is double.
#pragma once

#include <qd/config.hpp>
#include <qd/dataset.hpp>
#include <qd/planning.hpp>
#include <qd/representation.hpp>
#include <qd/rng.hpp>

#include <Eigen/Core>

#include <cstdint>
#include <iosfwd>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace qd::autoencoder {

// Per-epoch losses, appended in the run directory.
inline constexpr const char* kLossesFile = "losses.csv";

inline constexpr ParamSpec kParams[] = {
    param_int("hidden", "100", 1, 1e6, "units of the hidden ELU layer of encoder and decoder (HD)"),
    param_int("latent", "50", 1, 1e6, "latent size LD (must not exceed the policy's parameter count)"),
    param_float("learning_rate", "1e-5", 0.0, kUnbounded, "Adam learning rate"),
    param_float("beta1", "0.9", 0.0, 1.0, "Adam first-moment decay"),
    param_float("beta2", "0.999", 0.0, 1.0, "Adam second-moment decay"),
    param_float("epsilon", "1e-8", 0.0, kUnbounded,
                "Adam epsilon (TF form: added to sqrt(v), the bias correction is in the step size)"),
    param_int("batch_size", "64", 1, 1e9, "minibatch size; the last batch of an epoch may be smaller"),
    param_int("max_epochs", "20000", 0, 1e9, "epoch cap per fit() call"),
    param_string("test_split", "\"reference\"", "reference|random",
                 "reference: loop 0 has no test set, later loops test on the OLDEST test_fraction of D; "
                 "random: a random test_fraction of D in every loop (loop 0 included)"),
    param_float("test_fraction", "0.3", 0.0, 0.99, "fraction of D held out as test set (floor(fraction * N))"),
    param_int("early_stop_window", "100", 2, 1e9,
              "early stop looks at the last this-many test losses, from epoch index > window on"),
    param_float("early_stop_slope", "1e-5", -kUnbounded, kUnbounded,
                "stop when the least-squares slope of the window's test losses is >= this"),
    param_string("precision", "\"float32\"", "float32|float64", "scalar of training and inference"),
    param_int("threads", "0", 0, 1024,
              "threads of training (0 = all cores); results do not depend on it; inference runs on the "
              "calling thread"),
};

// Least-squares slope of y against x = 0..n-1 (what scipy's linregress returns as .slope).
double loss_slope(const double* y, std::size_t n);

// The reference early-stopping rule (README.md), evaluated after epoch `epoch` (0-based) when
// `test_losses` holds the test losses of epochs 0..epoch: stop iff epoch > window and the slope
// of the last `window` losses is >= min_slope.
bool should_stop(const std::vector<double>& test_losses, int epoch, int window, double min_slope);

// Row indices of the test and training sets for one fit() (README.md, test_split).
struct Split {
  std::vector<Eigen::Index> test;
  std::vector<Eigen::Index> train;
};
// reference: loop 0 -> no test set; loop >= 1 -> test = first floor(fraction*n) rows.
// random: floor(fraction*n) rows drawn without replacement from `rng` (in every loop).
Split make_split(std::size_t n, int loop, bool random_split, double fraction, Rng& rng);

struct Hyper {
  int hidden = 100;
  int latent = 50;
  double learning_rate = 1e-5;
  double beta1 = 0.9;
  double beta2 = 0.999;
  double epsilon = 1e-8;
  int batch_size = 64;
  int max_epochs = 20000;
  bool random_split = false;
  double test_fraction = 0.3;
  int early_stop_window = 100;
  double early_stop_slope = 1e-5;
  bool float64 = false;
  int threads = 0;
};

Hyper read_hyper(const Config& cfg);

// The precision-independent face of the network; Network<S> implements it.
class Model {
 public:
  virtual ~Model() = default;
  virtual FitReport fit(const Dataset& data, const FitContext& ctx) = 0;
  virtual void encode(const Matrix& theta, Matrix& z) const = 0;
  virtual void decode(const Matrix& z, Matrix& theta) const = 0;
  virtual void decoder_jacobians(const Matrix& z, std::vector<Matrix>& jacobians) const = 0;
  virtual void decoder_vjp(const Matrix& z, const Matrix& v, Matrix& out) const = 0;
  virtual void reconstruction_errors(const Matrix& theta, Vector& errors) const = 0;
  virtual void save(std::ostream& out) const = 0;
  virtual void load(std::istream& in) = 0;
  // Inspection for tests: every weight and bias concatenated, the Adam moments m and v
  // concatenated in the same order, and the Adam step count.
  virtual std::vector<double> weights() const = 0;
  virtual std::vector<double> adam_moments() const = 0;
  virtual std::int64_t adam_steps() const = 0;
};

std::unique_ptr<Model> make_model(const Hyper& hyper, int params, std::uint64_t seed);

class Autoencoder final : public Representation, public FitTimeEstimate {
 public:
  Autoencoder(const Config& cfg, const BuildContext& ctx);
  // For tests and benchmarks that do not go through a Config.
  Autoencoder(const Hyper& hyper, int params, std::uint64_t seed);

  int latent_size() const noexcept override { return hyper_.latent; }
  FitReport fit(const Dataset& data, const FitContext& ctx) override { return model_->fit(data, ctx); }
  void encode(const Matrix& theta, Matrix& z) const override { model_->encode(theta, z); }
  void decode(const Matrix& z, Matrix& theta) const override { model_->decode(z, theta); }
  void decoder_jacobians(const Matrix& z, std::vector<Matrix>& jacobians) const override {
    model_->decoder_jacobians(z, jacobians);
  }
  void decoder_vjp(const Matrix& z, const Matrix& v, Matrix& out) const override { model_->decoder_vjp(z, v, out); }
  void reconstruction_errors(const Matrix& theta, Vector& errors) const override {
    model_->reconstruction_errors(theta, errors);
  }
  // Times two epochs of a fresh model of this shape on random data (one thread) and scales them by
  // the rows and by the epochs each loop runs: max_epochs where there is no test set (loop 0 of the
  // reference split), early_stop_window + 2 otherwise, the fewest epochs early stopping allows and
  // what later loops of full-length runs take (README.md).
  std::vector<double> estimate_fit_seconds(const std::vector<std::size_t>& rows) const override;
  void save(std::ostream& out) const override { model_->save(out); }
  void load(std::istream& in) override { model_->load(in); }

  Model& model() noexcept { return *model_; }
  const Model& model() const noexcept { return *model_; }

 private:
  // Seconds per row and epoch of a fresh model of this shape trained on `probe_rows` random rows,
  // one thread: without a test set (loop 0 of the reference split) and with the later loops' one.
  std::pair<double, double> time_epochs(std::size_t probe_rows, int epochs) const;

  Hyper hyper_;
  int params_ = 0;
  std::unique_ptr<Model> model_;
};

// Epochs fit() runs at `loop` when early stopping stops it as soon as it may: max_epochs without a
// test set, else early_stop_window + 2 (capped by max_epochs).
int expected_epochs(const Hyper& hyper, int loop);

}  // namespace qd::autoencoder
