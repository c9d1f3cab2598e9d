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

double Rng::normal() noexcept {
  // Marsaglia polar method. The second value of the pair is dropped rather than cached, so the
  // whole generator state stays four words; fill_normal() uses both values of each pair.
  for (;;) {
    const double u = 2.0 * uniform() - 1.0;
    const double v = 2.0 * uniform() - 1.0;
    const double s = u * u + v * v;
    if (s > 0.0 && s < 1.0) return u * std::sqrt(-2.0 * std::log(s) / s);
  }
}

void Rng::fill_normal(double* out, std::size_t n, double scale) noexcept {
  std::size_t i = 0;
  while (i + 1 < n) {
    const double u = 2.0 * uniform() - 1.0;
    const double v = 2.0 * uniform() - 1.0;
    const double s = u * u + v * v;
    if (s <= 0.0 || s >= 1.0) continue;
    const double f = scale * std::sqrt(-2.0 * std::log(s) / s);
    out[i++] = u * f;
    out[i++] = v * f;
  }
  if (i < n) out[i] = scale * normal();
}

void Rng::fill_uniform(double* out, std::size_t n, double lo, double hi) noexcept {
  for (std::size_t i = 0; i < n; ++i) out[i] = uniform(lo, hi);
}

}  // namespace qd
