#include <qd/errors.hpp>
#include <qd/policy.hpp>
#include <qd/testing/policy_watch.hpp>

#include <atomic>
#include <cmath>
#include <map>
#include <mutex>
#include <thread>

namespace qd {
namespace {
// qd::testing's watch of Policy::load (policy_watch.hpp).
std::atomic<bool> g_watching{false};
std::mutex g_watch_mutex;
std::map<const Policy*, std::thread::id>& loaded_by() {
  static std::map<const Policy*, std::thread::id> m;
  return m;
}
bool g_two_threads = false;

void note_load(const Policy* p) {
  const std::lock_guard<std::mutex> lock(g_watch_mutex);
  const auto [it, fresh] = loaded_by().emplace(p, std::this_thread::get_id());
  if (!fresh && it->second != std::this_thread::get_id()) g_two_threads = true;
}
}  // namespace

namespace testing {
void watch_policy_loads(bool on) noexcept {
  const std::lock_guard<std::mutex> lock(g_watch_mutex);
  if (on) {
    loaded_by().clear();
    g_two_threads = false;
  }
  g_watching.store(on);
}

bool policy_loaded_on_two_threads() noexcept {
  const std::lock_guard<std::mutex> lock(g_watch_mutex);
  return g_two_threads;
}
}  // namespace testing

PolicyShape::PolicyShape(int inputs, std::vector<int> hidden, int outputs) : hidden_(std::move(hidden)) {
  QD_CHECK(inputs > 0 && outputs > 0, "policy needs at least one input and one output");
  sizes_.push_back(inputs);
  for (int h : hidden_) {
    QD_CHECK(h > 0, "hidden layer sizes must be positive");
    sizes_.push_back(h);
  }
  sizes_.push_back(outputs);
  offsets_.push_back(0);
  for (std::size_t l = 0; l + 1 < sizes_.size(); ++l)
    offsets_.push_back(offsets_.back() +
                       static_cast<std::size_t>(sizes_[l] + 1) * static_cast<std::size_t>(sizes_[l + 1]));
}

PolicyShape PolicyShape::direct(std::size_t parameters) {
  QD_CHECK(parameters > 0, "a direct parameter vector needs at least one parameter");
  PolicyShape s;
  s.offsets_ = {0, parameters};
  return s;
}

Policy::Policy(const PolicyShape& shape) : shape_(shape) {
  QD_CHECK(!shape.is_direct(), "a direct parameter vector (EnvironmentInfo::parameters) has no policy network");
  for (int l = 0; l < shape_.layers(); ++l) {
    weights_t_.emplace_back(shape_.layer_outputs(l), shape_.layer_inputs(l));
    biases_.emplace_back(shape_.layer_outputs(l));
    activations_.emplace_back(shape_.layer_outputs(l));
  }
}

void Policy::load(const double* theta) {
  if (g_watching.load(std::memory_order_relaxed)) note_load(this);
  for (int l = 0; l < shape_.layers(); ++l) {
    const int n_in = shape_.layer_inputs(l);
    const int n_out = shape_.layer_outputs(l);
    const double* block = theta + shape_.layer_offset(l);
    auto& w = weights_t_[static_cast<std::size_t>(l)];
    // Block is (n_in + 1) × n_out row-major: element (r, c) at r * n_out + c.
    for (int r = 0; r < n_in; ++r)
      for (int c = 0; c < n_out; ++c) w(c, r) = static_cast<float>(block[r * n_out + c]);
    auto& b = biases_[static_cast<std::size_t>(l)];
    for (int c = 0; c < n_out; ++c) b(c) = static_cast<float>(block[n_in * n_out + c]);
  }
}

const float* Policy::act(const float* observation) {
  Eigen::Map<const Eigen::VectorXf> x(observation, shape_.inputs());
  const int last = shape_.layers() - 1;
  for (int l = 0; l <= last; ++l) {
    auto& y = activations_[static_cast<std::size_t>(l)];
    const auto& w = weights_t_[static_cast<std::size_t>(l)];
    if (l == 0)
      y.noalias() = w * x;
    else
      y.noalias() = w * activations_[static_cast<std::size_t>(l - 1)];
    y += biases_[static_cast<std::size_t>(l)];
    if (l != last) y = y.array().tanh();
  }
  return activations_[static_cast<std::size_t>(last)].data();
}

}  // namespace qd
