#include <qd/rng.hpp>

#include <algorithm>
#include <cmath>

namespace qd {
namespace {

__extension__ using u128 = unsigned __int128;

std::uint64_t splitmix64(std::uint64_t& x) noexcept {
  std::uint64_t z = (x += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// Folds the key into one 64-bit value; each component goes through a full SplitMix64 round so
// that neighbouring keys (iteration 7 vs 8) give unrelated streams.
std::uint64_t hash_key(std::uint64_t seed, Stream stream, std::uint64_t a, std::uint64_t b, std::uint64_t c) noexcept {
  std::uint64_t h = seed;
  std::uint64_t x = splitmix64(h);
  for (std::uint64_t part : {static_cast<std::uint64_t>(stream), a, b, c}) {
    std::uint64_t y = x ^ (part + 0x632BE59BD9B4E019ull);
    x = splitmix64(y);
  }
  return x;
}

}  // namespace

Rng::Rng(std::uint64_t seed, Stream stream, std::uint64_t a, std::uint64_t b, std::uint64_t c) noexcept {
  std::uint64_t x = hash_key(seed, stream, a, b, c);
  for (auto& word : s_) word = splitmix64(x);
}

std::uint64_t Rng::derive_seed(std::uint64_t seed, Stream stream, std::uint64_t a, std::uint64_t b,
                               std::uint64_t c) noexcept {
  return hash_key(seed, stream, a, b, c);
}

std::uint64_t Rng::below(std::uint64_t n) noexcept {
  // Lemire, "Fast random integer generation in an interval" (2019).
  u128 m = static_cast<u128>(next()) * n;
  auto low = static_cast<std::uint64_t>(m);
  if (low < n) {
    const std::uint64_t threshold = (0 - n) % n;
    while (low < threshold) {
      m = static_cast<u128>(next()) * n;
      low = static_cast<std::uint64_t>(m);
    }
  }
  return static_cast<std::uint64_t>(m >> 64);
}

namespace {
constexpr double kZigR = 3.442619855899;       // start of the tail
constexpr double kZigV = 9.91256303526217e-3;  // area of each layer

// Marsaglia & Tsang, "The Ziggurat Method for Generating Random Variables" (2000): 128 layers of
// equal area under the right half of exp(-x²/2); layer 0 is the base strip plus the tail beyond r.
detail::ZigguratTables make_ziggurat() {
  detail::ZigguratTables t{};
  t.x[0] = kZigV / std::exp(-0.5 * kZigR * kZigR);
  t.x[1] = kZigR;
  for (int i = 1; i < 127; ++i)
    t.x[i + 1] = std::sqrt(-2.0 * std::log(kZigV / t.x[i] + std::exp(-0.5 * t.x[i] * t.x[i])));
  t.x[128] = 0.0;
  for (int i = 0; i <= 128; ++i) t.f[i] = std::exp(-0.5 * t.x[i] * t.x[i]);
  for (int i = 0; i < 128; ++i) t.ratio[i] = t.x[i + 1] / t.x[i];
  return t;
}
}  // namespace

const detail::ZigguratTables detail::kZiggurat = make_ziggurat();

double Rng::normal_outside_rectangle(unsigned layer, double u) noexcept {
  const auto& z = detail::kZiggurat;
  for (;;) {
    const double xx = u * z.x[layer];
    if (layer == 0) {
      // Tail beyond r (Marsaglia 1964).
      double a, b;
      do {
        a = -std::log(1.0 - uniform()) / kZigR;
        b = -std::log(1.0 - uniform());
      } while (2.0 * b < a * a);
      return u < 0 ? -(kZigR + a) : kZigR + a;
    }
    // Wedge between the rectangle and the curve.
    if (z.f[layer] + uniform() * (z.f[layer + 1] - z.f[layer]) < std::exp(-0.5 * xx * xx)) return xx;
    // Rejected: a fresh draw, whose rectangle test comes first again.
    const std::uint64_t bits = next();
    layer = static_cast<unsigned>(bits & 0x7F);
    u = 2.0 * static_cast<double>(bits >> 11) * 0x1.0p-53 - 1.0;
    if (std::fabs(u) < z.ratio[layer]) return u * z.x[layer];
  }
}

namespace {
// Bulk normals in two passes: first the raw 64-bit draws (the generator's serial dependency chain
// runs alone), then the rectangle test over the block. About 2.5x faster than calling normal() in a
// loop. The rare draws outside the rectangle take further values from the stream after the block,
// so the sequence differs from n calls of normal(); it is equally deterministic.
template <class Store>
void bulk_normal(Rng& rng, std::size_t n, Store store) noexcept {
  constexpr std::size_t kBlock = 256;
  std::uint64_t bits[kBlock];
  const auto& z = detail::kZiggurat;
  for (std::size_t i = 0; i < n; i += kBlock) {
    const std::size_t m = std::min(kBlock, n - i);
    for (std::size_t k = 0; k < m; ++k) bits[k] = rng.next();
    for (std::size_t k = 0; k < m; ++k) {
      const auto layer = static_cast<unsigned>(bits[k] & 0x7F);
      const double u = 2.0 * static_cast<double>(bits[k] >> 11) * 0x1.0p-53 - 1.0;
      const bool inside = std::fabs(u) < z.ratio[layer];
      store(i + k, inside ? u * z.x[layer] : rng.normal_outside_rectangle(layer, u));
    }
  }
}
}  // namespace

void Rng::fill_normal(double* out, std::size_t n, double scale) noexcept {
  bulk_normal(*this, n, [&](std::size_t i, double v) { out[i] = scale * v; });
}

void Rng::add_normal(double* out, std::size_t n, double scale) noexcept {
  bulk_normal(*this, n, [&](std::size_t i, double v) { out[i] += scale * v; });
}

void Rng::fill_uniform(double* out, std::size_t n, double lo, double hi) noexcept {
  for (std::size_t i = 0; i < n; ++i) out[i] = uniform(lo, hi);
}

}  // namespace qd
