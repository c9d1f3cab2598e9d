#include "autoencoder.hpp"

#include <qd/errors.hpp>
#include <qd/state_io.hpp>

#include <Eigen/Core>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <mutex>
#include <numeric>
#include <string>
#include <thread>
#include <tuple>
#include <utility>

namespace qd::autoencoder {

double loss_slope(const double* y, std::size_t n) {
  if (n < 2) return 0.0;
  // x = 0..n-1: closed-form mean and centred sum of squares.
  const double x_mean = 0.5 * static_cast<double>(n - 1);
  double y_mean = 0.0;
  for (std::size_t i = 0; i < n; ++i) y_mean += y[i];
  y_mean /= static_cast<double>(n);
  double sxy = 0.0, sxx = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double dx = static_cast<double>(i) - x_mean;
    sxy += dx * (y[i] - y_mean);
    sxx += dx * dx;
  }
  return sxy / sxx;
}

bool should_stop(const std::vector<double>& test_losses, int epoch, int window, double min_slope) {
  if (epoch <= window) return false;
  const auto w = static_cast<std::size_t>(window);
  if (test_losses.size() < w) return false;
  return loss_slope(test_losses.data() + (test_losses.size() - w), w) >= min_slope;
}

Split make_split(std::size_t n, int loop, bool random_split, double fraction, Rng& rng) {
  Split split;
  std::size_t n_test = 0;
  if (random_split || loop > 0) n_test = static_cast<std::size_t>(std::floor(fraction * static_cast<double>(n)));
  std::vector<char> is_test(n, 0);
  if (random_split) {
    // Partial Fisher-Yates: the first n_test slots become a uniform random subset.
    std::vector<Eigen::Index> perm(n);
    std::iota(perm.begin(), perm.end(), Eigen::Index{0});
    for (std::size_t i = 0; i < n_test; ++i) {
      const std::size_t j = i + static_cast<std::size_t>(rng.below(n - i));
      std::swap(perm[i], perm[j]);
      is_test[static_cast<std::size_t>(perm[i])] = 1;
    }
  } else {
    std::fill(is_test.begin(), is_test.begin() + static_cast<std::ptrdiff_t>(n_test), 1);
  }
  for (std::size_t i = 0; i < n; ++i) (is_test[i] ? split.test : split.train).push_back(static_cast<Eigen::Index>(i));
  return split;
}

Hyper read_hyper(const Config& cfg) {
  Hyper h;
  h.hidden = static_cast<int>(cfg.get_int("hidden"));
  h.latent = static_cast<int>(cfg.get_int("latent"));
  h.learning_rate = cfg.get_float("learning_rate");
  h.beta1 = cfg.get_float("beta1");
  h.beta2 = cfg.get_float("beta2");
  h.epsilon = cfg.get_float("epsilon");
  h.batch_size = static_cast<int>(cfg.get_int("batch_size"));
  h.max_epochs = static_cast<int>(cfg.get_int("max_epochs"));
  h.random_split = cfg.get_string("test_split") == "random";
  h.test_fraction = cfg.get_float("test_fraction");
  h.early_stop_window = static_cast<int>(cfg.get_int("early_stop_window"));
  h.early_stop_slope = cfg.get_float("early_stop_slope");
  h.float64 = cfg.get_string("precision") == "float64";
  h.threads = static_cast<int>(cfg.get_int("threads"));
  return h;
}

namespace {

// Training splits the P dimension into column chunks whose number depends on P only, never on
// the thread count: each chunk's products are computed by one thread (Eigen single-threaded) and
// partial sums over chunks are added in chunk order. The thread count therefore only decides who
// computes a chunk, and results are bitwise identical for any `threads`. (Eigen's own OpenMP GEMM
// changes its blocking, hence its rounding, with the thread count, and forks once per product.)
// 4 chunks per started 2048 columns: balanced for 1, 2 and 4 threads, and each chunk's K stays
// <= 512, because Eigen 3.4's float GEMM with 64-row operands collapses from ~125 to ~10 GFLOPS
// on this CPU (AVX-512) for inner sizes between ~520 and ~940 (measured; see README).
int chunk_count(Eigen::Index params) {
  return static_cast<int>(4 * ((params + 2047) / 2048));
}

int resolve_threads(int threads) {
  return threads > 0 ? threads : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

template <class S>
class Network final : public Model {
 public:
  using Mat = Eigen::Matrix<S, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  using Row = Eigen::Matrix<S, 1, Eigen::Dynamic>;
  using Flat = Eigen::Matrix<S, Eigen::Dynamic, 1>;
  using MapMat = Eigen::Map<Mat>;
  using MapRow = Eigen::Map<Row>;

  // Views of one flat buffer (parameters, gradients or an Adam moment) as the eight tensors, in
  // the order We1 be1 We2 be2 Wd1 bd1 Wd2 bd2. Kernels are (inputs x outputs), Keras' layout.
  struct Views {
    MapMat We1, We2, Wd1, Wd2;
    MapRow be1, be2, bd1, bd2;
    Views(S* p, Eigen::Index P, Eigen::Index H, Eigen::Index L)
        : We1(p, P, H),
          We2(p + P * H + H, H, L),
          Wd1(p + P * H + H + H * L + L, L, H),
          Wd2(p + P * H + H + H * L + L + L * H + H, H, P),
          be1(p + P * H, H),
          be2(p + P * H + H + H * L, L),
          bd1(p + P * H + H + H * L + L + L * H, H),
          bd2(p + P * H + H + H * L + L + L * H + H + H * P, P) {}
  };

  Network(const Hyper& hyper, int params, std::uint64_t seed)
      : hyper_(hyper),
        P_(params),
        H_(hyper.hidden),
        L_(hyper.latent),
        size_(P_ * H_ + H_ + H_ * L_ + L_ + L_ * H_ + H_ + H_ * P_ + P_),
        chunks_(chunk_count(P_)),
        theta_(Flat::Zero(size_)),
        grad_(Flat::Zero(size_)),
        m_(Flat::Zero(size_)),
        v_(Flat::Zero(size_)),
        w_(theta_.data(), P_, H_, L_),
        g_(grad_.data(), P_, H_, L_),
        m_views_(m_.data(), P_, H_, L_),
        v_views_(v_.data(), P_, H_, L_) {
    // Eigen would run every product with all OpenMP threads (we compile with -fopenmp): keep it
    // serial; training parallelises itself (column chunks) and inference must stay cheap to call from
    // concurrent evaluation workers.
    Eigen::setNbThreads(1);
    // Glorot-uniform kernels (limit sqrt(6 / (fan_in + fan_out))), zero biases (Keras defaults).
    Rng rng(seed, Stream::kModelInit);
    for (MapMat* k : {&w_.We1, &w_.We2, &w_.Wd1, &w_.Wd2}) {
      const double limit = std::sqrt(6.0 / static_cast<double>(k->rows() + k->cols()));
      for (Eigen::Index r = 0; r < k->rows(); ++r)
        for (Eigen::Index c = 0; c < k->cols(); ++c) (*k)(r, c) = static_cast<S>(rng.uniform(-limit, limit));
    }
  }

  // ---- training ------------------------------------------------------------------------------
  FitReport fit(const Dataset& data, const FitContext& ctx) override {
    QD_CHECK(static_cast<Eigen::Index>(data.param_count()) == P_, "autoencoder: dataset has another param count");
    const int threads = resolve_threads(hyper_.threads);
    FitReport report;
    report.train_loss = std::nan("");
    report.test_loss = std::nan("");
    // As the reference (README.md): the optimiser state restarts every loop; the weights warm-start.
    m_.setZero();
    v_.setZero();
    steps_ = 0;

    const std::size_t n = data.size();
    Rng rng(ctx.seed, Stream::kTraining, static_cast<std::uint64_t>(ctx.loop));
    const Split split = make_split(n, ctx.loop, hyper_.random_split, hyper_.test_fraction, rng);
    if (split.train.empty()) return report;

    const auto all = data.params();
    const Mat x_train = gather(all, split.train);
    const Mat x_test = gather(all, split.test);
    const bool has_test = x_test.rows() > 0;

    // The losses file gets its header even before the first epoch (the core writes it once).
    constexpr const char* kHeader = "loop,epoch,train_loss,test_loss\n";
    if (ctx.log) ctx.log->append(kLossesFile, kHeader, "");

    const Eigen::Index n_train = x_train.rows();
    std::vector<Eigen::Index> order(static_cast<std::size_t>(n_train));
    std::vector<double> test_losses;
    Workspace ws;
    Mat batch;
    char line[128];
    for (int epoch = 0; epoch < hyper_.max_epochs; ++epoch) {
      std::iota(order.begin(), order.end(), Eigen::Index{0});
      for (std::size_t i = order.size() - 1; i > 0; --i) std::swap(order[i], order[rng.below(i + 1)]);
      double loss_sum = 0.0;
      int batches = 0;
      for (Eigen::Index start = 0; start < n_train; start += hyper_.batch_size) {
        const Eigen::Index b = std::min<Eigen::Index>(hyper_.batch_size, n_train - start);
        batch.resize(b, P_);
        for (Eigen::Index r = 0; r < b; ++r) batch.row(r) = x_train.row(order[static_cast<std::size_t>(start + r)]);
        loss_sum += train_step(batch, ws, threads);
        ++batches;
      }
      // Reference: the epoch's training loss is the plain mean of the minibatch losses.
      report.train_loss = loss_sum / batches;
      report.epochs = epoch + 1;
      if (has_test) {
        report.test_loss = mean_sse(x_test, threads);
        test_losses.push_back(report.test_loss);
      }
      if (ctx.log) {
        if (has_test)
          std::snprintf(line, sizeof line, "%d,%d,%.9g,%.9g\n", ctx.loop, epoch, report.train_loss, report.test_loss);
        else
          std::snprintf(line, sizeof line, "%d,%d,%.9g,\n", ctx.loop, epoch, report.train_loss);
        ctx.log->append(kLossesFile, kHeader, line);  // row by row, so the file shows the training live
      }
      if (has_test && should_stop(test_losses, epoch, hyper_.early_stop_window, hyper_.early_stop_slope)) {
        report.stopped_early = true;
        break;
      }
    }
    return report;
  }

  // ---- inference (thread-safe: locals only) --------------------------------------------------
  void encode(const Matrix& theta, Matrix& z) const override {
    QD_CHECK(theta.cols() == P_, "autoencoder::encode: wrong parameter count");
    Mat a1, zs;
    encode_to(theta.template cast<S>(), a1, zs);
    z = zs.template cast<double>();
  }

  void decode(const Matrix& z, Matrix& theta) const override {
    QD_CHECK(z.cols() == L_, "autoencoder::decode: wrong latent size");
    Mat a2, y;
    decode_to(z.template cast<S>(), a2, y);
    theta = y.template cast<double>();
  }

  // J(z) = Wd2ᵀ diag(elu'(z Wd1 + bd1)) Wd1ᵀ (P x LD; kernels are stored inputs x outputs).
  void decoder_jacobians(const Matrix& z, std::vector<Matrix>& jacobians) const override {
    QD_CHECK(z.cols() == L_, "autoencoder::decoder_jacobians: wrong latent size");
    const Mat zs = z.template cast<S>();
    Mat a(1, H_), scaled(H_, L_), jac(P_, L_);
    jacobians.resize(static_cast<std::size_t>(z.rows()));
    for (Eigen::Index i = 0; i < zs.rows(); ++i) {
      a.noalias() = zs.row(i) * w_.Wd1;
      a += w_.bd1;
      elu_derivative_in_place(a);
      scaled.noalias() = a.transpose().asDiagonal() * w_.Wd1.transpose();
      jac.noalias() = w_.Wd2.transpose() * scaled;
      jacobians[static_cast<std::size_t>(i)] = jac.template cast<double>();
    }
  }

  // out_i = J(z_i)ᵀ v_i = Wd1 (elu'(z_i Wd1 + bd1) ⊙ (Wd2 v_i)), batched, without forming J.
  void decoder_vjp(const Matrix& z, const Matrix& v, Matrix& out) const override {
    QD_CHECK(z.cols() == L_ && v.cols() == P_ && z.rows() == v.rows(), "autoencoder::decoder_vjp: shape mismatch");
    const Mat zs = z.template cast<S>();
    const Mat vs = v.template cast<S>();
    Mat a(zs.rows(), H_), g(zs.rows(), H_), o(zs.rows(), L_);
    a.noalias() = zs * w_.Wd1;
    a.rowwise() += w_.bd1;
    elu_derivative_in_place(a);
    g.noalias() = vs * w_.Wd2.transpose();
    g.array() *= a.array();
    o.noalias() = g * w_.Wd1.transpose();
    out = o.template cast<double>();
  }

  void reconstruction_errors(const Matrix& theta, Vector& errors) const override {
    QD_CHECK(theta.cols() == P_, "autoencoder::reconstruction_errors: wrong parameter count");
    const Mat x = theta.template cast<S>();
    Mat a1, z, a2, y;
    encode_to(x, a1, z);
    decode_to(z, a2, y);
    // Measured against the double input, as the core's default does.
    errors = (theta - y.template cast<double>()).rowwise().norm();
  }

  // ---- state ---------------------------------------------------------------------------------
  void save(std::ostream& out) const override {
    state::write_tag(out, "AENC");
    state::write<std::uint32_t>(out, 1);  // format version
    state::write<std::uint32_t>(out, sizeof(S));
    state::write<std::int64_t>(out, P_);
    state::write<std::int64_t>(out, H_);
    state::write<std::int64_t>(out, L_);
    state::write<std::int64_t>(out, steps_);
    state::write_matrix(out, theta_);
    state::write_matrix(out, m_);
    state::write_matrix(out, v_);
  }

  void load(std::istream& in) override {
    state::expect_tag(in, "AENC");
    if (state::read<std::uint32_t>(in) != 1) throw StateError("autoencoder: unknown state format version");
    const auto width = state::read<std::uint32_t>(in);
    if (width != sizeof(S))
      throw StateError("autoencoder: state blob is float" + std::to_string(8 * width) + ", the model is float" +
                       std::to_string(8 * sizeof(S)) + " (precision)");
    const auto p = state::read<std::int64_t>(in);
    const auto h = state::read<std::int64_t>(in);
    const auto l = state::read<std::int64_t>(in);
    if (p != P_ || h != H_ || l != L_)
      throw StateError("autoencoder: state blob has shape P=" + std::to_string(p) + " hidden=" + std::to_string(h) +
                       " latent=" + std::to_string(l) + ", the model has P=" + std::to_string(P_) +
                       " hidden=" + std::to_string(H_) + " latent=" + std::to_string(L_));
    const auto steps = state::read<std::int64_t>(in);
    Flat theta, m, v;
    state::read_matrix(in, theta);
    state::read_matrix(in, m);
    state::read_matrix(in, v);
    if (theta.size() != size_ || m.size() != size_ || v.size() != size_)
      throw StateError("autoencoder: state blob has buffers of the wrong size");
    // Copy into the existing buffers: the Views point into them.
    theta_ = theta;
    m_ = m;
    v_ = v;
    steps_ = steps;
  }

  std::vector<double> weights() const override { return to_vector(theta_); }
  std::vector<double> adam_moments() const override {
    std::vector<double> out = to_vector(m_);
    const std::vector<double> second = to_vector(v_);
    out.insert(out.end(), second.begin(), second.end());
    return out;
  }
  std::int64_t adam_steps() const override { return steps_; }

 private:
  struct Workspace {
    Mat a1, h1, z, a2, h2, y, dh2, dz;
    std::vector<Mat> part;           // per-chunk partial products (B x H)
    std::vector<double> chunk_loss;  // per-chunk SSE
  };

  // Column range of chunk c of P: multiples of 16 (one AVX-512 float register) but the last.
  std::pair<Eigen::Index, Eigen::Index> chunk(int c) const {
    const Eigen::Index len = ((P_ + chunks_ - 1) / chunks_ + 15) / 16 * 16;
    const Eigen::Index begin = std::min<Eigen::Index>(P_, c * len);
    return {begin, std::min<Eigen::Index>(P_, begin + len) - begin};
  }

  static Mat gather(const Eigen::Map<const qd::Matrix>& all, const std::vector<Eigen::Index>& rows) {
    Mat out(static_cast<Eigen::Index>(rows.size()), all.cols());
    for (std::size_t i = 0; i < rows.size(); ++i)
      out.row(static_cast<Eigen::Index>(i)) = all.row(rows[i]).template cast<S>();
    return out;
  }

  static std::vector<double> to_vector(const Flat& f) {
    std::vector<double> out(static_cast<std::size_t>(f.size()));
    for (Eigen::Index i = 0; i < f.size(); ++i) out[static_cast<std::size_t>(i)] = static_cast<double>(f[i]);
    return out;
  }

  // elu(a) = a for a > 0, exp(a) - 1 otherwise.
  static void elu(const Mat& a, Mat& h) {
    h.resize(a.rows(), a.cols());
    h.array() = (a.array() > S(0)).select(a.array(), a.array().exp() - S(1));
  }
  // elu'(a) = 1 for a > 0, exp(a) otherwise.
  static void elu_derivative_in_place(Mat& a) { a.array() = (a.array() > S(0)).select(S(1), a.array().exp()); }

  template <class In>
  void encode_to(const In& x, Mat& a1, Mat& z) const {
    a1.resize(x.rows(), H_);
    a1.noalias() = x * w_.We1;
    a1.rowwise() += w_.be1;
    a1.array() = (a1.array() > S(0)).select(a1.array(), a1.array().exp() - S(1));
    z.resize(x.rows(), L_);
    z.noalias() = a1 * w_.We2;
    z.rowwise() += w_.be2;
  }

  template <class In>
  void decode_to(const In& z, Mat& a2, Mat& y) const {
    a2.resize(z.rows(), H_);
    a2.noalias() = z * w_.Wd1;
    a2.rowwise() += w_.bd1;
    a2.array() = (a2.array() > S(0)).select(a2.array(), a2.array().exp() - S(1));
    y.resize(z.rows(), P_);
    y.noalias() = a2 * w_.Wd2;
    y.rowwise() += w_.bd2;
  }

  // Mean over rows of the per-row SSE. Row blocks of fixed size, summed in block order, so the
  // result does not depend on the thread count.
  double mean_sse(const Mat& x, int threads) const {
    constexpr Eigen::Index kBlock = 256;
    const Eigen::Index blocks = (x.rows() + kBlock - 1) / kBlock;
    std::vector<double> sse(static_cast<std::size_t>(blocks), 0.0);
#pragma omp parallel for schedule(static) num_threads(threads)
    for (Eigen::Index k = 0; k < blocks; ++k) {
      const Eigen::Index start = k * kBlock;
      const Eigen::Index b = std::min(kBlock, x.rows() - start);
      const auto block = x.middleRows(start, b);
      Mat a1, z, a2, y;
      encode_to(block, a1, z);
      decode_to(z, a2, y);
      y -= block;
      sse[static_cast<std::size_t>(k)] = static_cast<double>(y.squaredNorm());
    }
    double total = 0.0;
    for (double v : sse) total += v;
    return total / static_cast<double>(x.rows());
  }

  // One Adam step on one minibatch; returns the batch loss (mean per-sample SSE) before the step.
  // The big products (everything touching P) run per column chunk of P in parallel; the small
  // HD/LD layers run on one thread between the chunked phases.
  double train_step(const Mat& x, Workspace& ws, int threads) {
    const Eigen::Index b = x.rows();
    ws.a1.resize(b, H_);
    ws.h1.resize(b, H_);
    ws.z.resize(b, L_);
    ws.a2.resize(b, H_);
    ws.h2.resize(b, H_);
    ws.y.resize(b, P_);
    ws.dh2.resize(b, H_);
    ws.dz.resize(b, L_);
    ws.part.resize(static_cast<std::size_t>(chunks_));
    ws.chunk_loss.assign(static_cast<std::size_t>(chunks_), 0.0);
    for (Mat& part : ws.part) part.resize(b, H_);
    const S grad_scale = S(2) / static_cast<S>(b);  // d(mean SSE)/dy = 2 (y - x) / b
    const AdamStep k = adam_step();

#pragma omp parallel num_threads(threads)
    {
      // Forward, first layer: x We1 as a sum over chunks of P.
#pragma omp for schedule(static)
      for (int c = 0; c < chunks_; ++c) {
        const auto [begin, len] = chunk(c);
        if (len == 0) {
          ws.part[c].setZero();
        } else {
          ws.part[c].noalias() = x.middleCols(begin, len) * w_.We1.middleRows(begin, len);
        }
      }
#pragma omp single
      {
        ws.a1 = ws.part[0];
        for (int c = 1; c < chunks_; ++c) ws.a1 += ws.part[c];
        ws.a1.rowwise() += w_.be1;
        elu(ws.a1, ws.h1);
        ws.z.noalias() = ws.h1 * w_.We2;
        ws.z.rowwise() += w_.be2;
        ws.a2.noalias() = ws.z * w_.Wd1;
        ws.a2.rowwise() += w_.bd1;
        elu(ws.a2, ws.h2);
      }
      // Output layer, its gradients and the gradient into h2, per chunk of P.
#pragma omp for schedule(static)
      for (int c = 0; c < chunks_; ++c) {
        const auto [begin, len] = chunk(c);
        if (len == 0) {
          ws.part[c].setZero();
          ws.chunk_loss[c] = 0.0;
          continue;
        }
        auto dy = ws.y.middleCols(begin, len);
        dy.noalias() = ws.h2 * w_.Wd2.middleCols(begin, len);
        dy.rowwise() += w_.bd2.segment(begin, len);
        dy -= x.middleCols(begin, len);  // residual
        ws.chunk_loss[c] = static_cast<double>(dy.squaredNorm());
        dy *= grad_scale;
        g_.Wd2.middleCols(begin, len).noalias() = ws.h2.transpose() * dy;
        g_.bd2.segment(begin, len).noalias() = dy.colwise().sum();
        ws.part[c].noalias() = dy * w_.Wd2.middleCols(begin, len).transpose();
        // This chunk of Wd2 and bd2 is read by no other thread in this step: update it now.
        adam(k, w_.Wd2.middleCols(begin, len), m_views_.Wd2.middleCols(begin, len), v_views_.Wd2.middleCols(begin, len),
             g_.Wd2.middleCols(begin, len));
        adam(k, w_.bd2.segment(begin, len), m_views_.bd2.segment(begin, len), v_views_.bd2.segment(begin, len),
             g_.bd2.segment(begin, len));
      }
#pragma omp single
      {
        // Backward through the small layers; elu'(a) = h + 1 where a <= 0.
        ws.dh2 = ws.part[0];
        for (int c = 1; c < chunks_; ++c) ws.dh2 += ws.part[c];
        ws.dh2.array() = (ws.a2.array() > S(0)).select(ws.dh2.array(), ws.dh2.array() * (ws.h2.array() + S(1)));
        g_.Wd1.noalias() = ws.z.transpose() * ws.dh2;
        g_.bd1.noalias() = ws.dh2.colwise().sum();
        ws.dz.noalias() = ws.dh2 * w_.Wd1.transpose();
        g_.We2.noalias() = ws.h1.transpose() * ws.dz;
        g_.be2.noalias() = ws.dz.colwise().sum();
        Mat& dh1 = ws.part[0];  // reuse: the partials are consumed
        dh1.noalias() = ws.dz * w_.We2.transpose();
        dh1.array() = (ws.a1.array() > S(0)).select(dh1.array(), dh1.array() * (ws.h1.array() + S(1)));
        g_.be1.noalias() = dh1.colwise().sum();
        adam(k, w_.Wd1, m_views_.Wd1, v_views_.Wd1, g_.Wd1);
        adam(k, w_.bd1, m_views_.bd1, v_views_.bd1, g_.bd1);
        adam(k, w_.We2, m_views_.We2, v_views_.We2, g_.We2);
        adam(k, w_.be2, m_views_.be2, v_views_.be2, g_.be2);
        adam(k, w_.be1, m_views_.be1, v_views_.be1, g_.be1);
      }
      // First-layer kernel gradient and its Adam step, per chunk of rows of We1.
#pragma omp for schedule(static)
      for (int c = 0; c < chunks_; ++c) {
        const auto [begin, len] = chunk(c);
        if (len == 0) continue;
        g_.We1.middleRows(begin, len).noalias() = x.middleCols(begin, len).transpose() * ws.part[0];
        adam(k, w_.We1.middleRows(begin, len), m_views_.We1.middleRows(begin, len), v_views_.We1.middleRows(begin, len),
             g_.We1.middleRows(begin, len));
      }
    }
    ++steps_;
    double sse = 0.0;
    for (double v : ws.chunk_loss) sse += v;
    return sse / static_cast<double>(b);
  }

  // TF 1.x Adam (the reference's) at step t = steps_ + 1:
  // lr_t = lr sqrt(1 - b2^t) / (1 - b1^t); m = b1 m + (1 - b1) g; v = b2 v + (1 - b2) g^2;
  // theta -= lr_t m / (sqrt(v) + eps). Element-wise, so any partition of the tensors among
  // threads gives the same bits.
  struct AdamStep {
    S b1, b2, lr_t, eps;
  };
  AdamStep adam_step() const {
    const double t = static_cast<double>(steps_ + 1);
    return {static_cast<S>(hyper_.beta1), static_cast<S>(hyper_.beta2),
            static_cast<S>(hyper_.learning_rate * std::sqrt(1.0 - std::pow(hyper_.beta2, t)) /
                           (1.0 - std::pow(hyper_.beta1, t))),
            static_cast<S>(hyper_.epsilon)};
  }
  // An IEEE square root, never Eigen's float `sqrt()`: with EIGEN_FAST_MATH (its default) that is
  // rsqrtps plus a Newton step on AVX2, and rsqrtps is an approximation each CPU vendor rounds its
  // own way, so the same x86-64-v3 binary trained to other bits on AMD and Intel CPUs.
  struct ExactSqrt {
    S operator()(S x) const { return std::sqrt(x); }
  };
  template <class Block, class Grad>
  static void adam(const AdamStep& k, Block theta, Block m, Block v, const Grad& g) {
    m.array() = k.b1 * m.array() + (S(1) - k.b1) * g.array();
    v.array() = k.b2 * v.array() + (S(1) - k.b2) * g.array().square();
    theta.array() -= k.lr_t * m.array() / (v.array().unaryExpr(ExactSqrt{}) + k.eps);
  }

  Hyper hyper_;
  Eigen::Index P_, H_, L_, size_;
  int chunks_;
  Flat theta_, grad_, m_, v_;
  Views w_, g_, m_views_, v_views_;  // views of theta_, grad_, m_, v_
  std::int64_t steps_ = 0;
};

}  // namespace

std::unique_ptr<Model> make_model(const Hyper& hyper, int params, std::uint64_t seed) {
  if (hyper.float64) return std::make_unique<Network<double>>(hyper, params, seed);
  return std::make_unique<Network<float>>(hyper, params, seed);
}

namespace {
int policy_params(const BuildContext& ctx) {
  if (!ctx.policy) throw ConfigError("type", "the autoencoder needs the policy shape (build it after the descriptor)");
  return static_cast<int>(ctx.policy->param_count());
}
}  // namespace

Autoencoder::Autoencoder(const Config& cfg, const BuildContext& ctx) : hyper_(read_hyper(cfg)) {
  const int params = policy_params(ctx);
  params_ = params;
  if (hyper_.latent > params)
    throw ConfigError("latent", "latent = " + std::to_string(hyper_.latent) + " exceeds the policy's parameter count " +
                                    std::to_string(params));
  model_ = make_model(hyper_, params, ctx.seed);
}

Autoencoder::Autoencoder(const Hyper& hyper, int params, std::uint64_t seed) : hyper_(hyper), params_(params) {
  if (hyper_.latent > params)
    throw ConfigError("latent", "latent = " + std::to_string(hyper_.latent) + " exceeds the policy's parameter count " +
                                    std::to_string(params));
  model_ = make_model(hyper_, params, seed);
}

int expected_epochs(const Hyper& hyper, int loop) {
  const bool has_test = hyper.random_split || loop > 0;
  return has_test ? std::min(hyper.max_epochs, hyper.early_stop_window + 2) : hyper.max_epochs;
}

std::vector<double> Autoencoder::estimate_fit_seconds(const std::vector<std::size_t>& rows) const {
  std::vector<double> seconds(rows.size(), 0.0);
  if (rows.empty()) return seconds;
  // An epoch costs time linear in the rows (minibatches of a fixed size): time one at a probe size
  // and scale. Two probes, because an epoch without a test set trains on every row, and one with
  // it trains on (1 - test_fraction) of them and evaluates the rest.
  constexpr int kProbeEpochs = 2;
  const std::size_t largest = *std::max_element(rows.begin(), rows.end());
  const std::size_t probe_rows = std::clamp<std::size_t>(largest, 256, 1024);
  // A sweep asks once per run, mostly about the same shapes: each shape is timed once per process.
  using ProbeKey = std::tuple<int, int, int, int, bool, bool, double, std::size_t>;
  static std::mutex cache_mutex;
  static std::map<ProbeKey, std::pair<double, double>> cache;
  const ProbeKey key{params_,        hyper_.hidden,       hyper_.latent,        hyper_.batch_size,
                     hyper_.float64, hyper_.random_split, hyper_.test_fraction, probe_rows};
  const std::lock_guard<std::mutex> lock(cache_mutex);
  auto cached = cache.find(key);
  if (cached == cache.end()) cached = cache.emplace(key, time_epochs(probe_rows, kProbeEpochs)).first;
  const auto [first, later] = cached->second;
  for (std::size_t loop = 0; loop < rows.size(); ++loop) {
    const int epochs = expected_epochs(hyper_, static_cast<int>(loop));
    seconds[loop] = epochs * (loop == 0 ? first : later) * static_cast<double>(rows[loop]);
  }
  return seconds;
}

std::pair<double, double> Autoencoder::time_epochs(std::size_t probe_rows, int epochs) const {
  Dataset data(static_cast<std::size_t>(params_));
  Rng rng(0, Stream::kTraining, 0);
  std::vector<double> theta(static_cast<std::size_t>(params_));
  for (std::size_t r = 0; r < probe_rows; ++r) {
    for (double& x : theta) x = rng.uniform(-1.0, 1.0);
    data.add(theta.data(), static_cast<std::int64_t>(r), 0);
  }
  auto seconds_per_row_epoch = [&](int loop) {
    Hyper probe = hyper_;
    probe.threads = 1;  // core-seconds
    probe.max_epochs = epochs;
    // The fastest of a few probes (at least 0.2 s in all): an idle machine's time, without the
    // scheduler's noise on a probe of a few milliseconds.
    double best = std::numeric_limits<double>::infinity(), spent = 0.0;
    for (int probe_run = 0; probe_run < 20 && (probe_run < 3 || spent < 0.2); ++probe_run) {
      const auto model = make_model(probe, params_, 0);
      const auto start = std::chrono::steady_clock::now();
      const FitReport report = model->fit(data, FitContext{loop, 0, nullptr});
      const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      spent += elapsed;
      best = std::min(best, elapsed / (std::max(1, report.epochs) * static_cast<double>(probe_rows)));
    }
    return best;
  };
  const double first = seconds_per_row_epoch(0);
  return {first, hyper_.random_split ? first : seconds_per_row_epoch(1)};
}

}  // namespace qd::autoencoder
