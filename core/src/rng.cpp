#include <qd/rng.hpp>

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

// Ziggurat tables (Marsaglia & Tsang, "The Ziggurat Method for Generating Random Variables", 2000):
// 128 layers of equal area v under the right half of f(x) = exp(-x²/2); layer 0 is the base strip
// plus the tail beyond r. x[i] is the right edge of layer i's rectangle, f[i] = f(x[i]).
struct ZigguratTables {
  static constexpr int kLayers = 128;
  static constexpr double kR = 3.442619855899;
  static constexpr double kV = 9.91256303526217e-3;
  double x[kLayers + 1];
  double f[kLayers + 1];
  ZigguratTables() {
    x[0] = kV / std::exp(-0.5 * kR * kR);
    x[1] = kR;
    for (int i = 1; i < kLayers - 1; ++i) x[i + 1] = std::sqrt(-2.0 * std::log(kV / x[i] + std::exp(-0.5 * x[i] * x[i])));
    x[kLayers] = 0.0;
    for (int i = 0; i <= kLayers; ++i) f[i] = std::exp(-0.5 * x[i] * x[i]);
  }
};
const ZigguratTables& zig() {
  static const ZigguratTables t;
  return t;
}

}  // namespace

double Rng::normal() noexcept {
  const ZigguratTables& z = zig();
  for (;;) {
    const std::uint64_t bits = next();
    const int i = static_cast<int>(bits & 0x7F);                         // layer: low 7 bits
    const double u = 2.0 * static_cast<double>(bits >> 11) * 0x1.0p-53 - 1.0;  // signed: top 53 bits
    const double xx = u * z.x[i];
    if (std::fabs(u) < z.x[i + 1] / z.x[i]) return xx;  // inside the rectangle: ~99% of draws
    if (i == 0) {
      // Tail beyond r (Marsaglia 1964).
      double a, b;
      do {
        a = -std::log(1.0 - uniform()) / ZigguratTables::kR;
        b = -std::log(1.0 - uniform());
      } while (2.0 * b < a * a);
      return u < 0 ? -(ZigguratTables::kR + a) : ZigguratTables::kR + a;
    }
    // Wedge between the rectangle and the curve.
    if (z.f[i] + uniform() * (z.f[i + 1] - z.f[i]) < std::exp(-0.5 * xx * xx)) return xx;
  }
}

void Rng::fill_normal(double* out, std::size_t n, double scale) noexcept {
  for (std::size_t i = 0; i < n; ++i) out[i] = scale * normal();
}

void Rng::add_normal(double* out, std::size_t n, double scale) noexcept {
  for (std::size_t i = 0; i < n; ++i) out[i] += scale * normal();
}

void Rng::fill_uniform(double* out, std::size_t n, double lo, double hi) noexcept {
  for (std::size_t i = 0; i < n; ++i) out[i] = uniform(lo, hi);
}

}  // namespace qd
