// Explicit, seedable random streams. There is no global RNG anywhere in qdrun.
//
// Every stream is derived from the run seed and a key that says what it is for (purpose, loop,
// iteration, index), never from a thread or rank. That is what makes a run bit-identical with
// 1 worker, N workers or N MPI ranks, and what lets a checkpoint resume without saving RNG state.
//
// Engine: xoshiro256++ (Blackman & Vigna), seeded through SplitMix64 from a hash of the key.
// Normals: the Ziggurat method (Marsaglia & Tsang 2000). Both are implemented here, so the sequence does not depend on
// the standard library's distribution implementations.
#pragma once

#include <qd/export.hpp>

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>

namespace qd {

// What a stream is for. Plugins use kPlugin plus their own sub-keys.
enum class Stream : std::uint64_t {
  kInitial = 1,    // loop-0 sampling            (key: loop)
  kSelection = 2,  // parent selection           (key: loop, iteration)
  kMutation = 3,   // mutation operators          (key: loop, iteration)
  kInsertion = 4,  // coin-flip replacements      (key: loop, iteration)
  kEpisode = 5,    // per-episode seeds           (key: loop, iteration, offspring)
  kTraining = 6,   // representation training    (key: loop)
  kModelInit = 7,  // representation weights      (key: none)
  kPlugin = 100,
};

namespace detail {
// Ziggurat tables (128 layers): x[i] is the right edge of layer i, f[i] = exp(-x[i]²/2),
// ratio[i] = x[i+1] / x[i]. Built once when libqd_core loads.
struct ZigguratTables {
  double x[129];
  double f[129];
  double ratio[128];
};
QD_EXPORT extern const ZigguratTables kZiggurat;
}  // namespace detail

class QD_EXPORT Rng {
 public:
  using State = std::array<std::uint64_t, 4>;

  Rng(std::uint64_t seed, Stream stream, std::uint64_t a = 0, std::uint64_t b = 0, std::uint64_t c = 0) noexcept;
  explicit Rng(const State& state) noexcept : s_(state) {}

  // A 64-bit seed for something that takes a plain seed (an environment episode, a sub-stream).
  static std::uint64_t derive_seed(std::uint64_t seed, Stream stream, std::uint64_t a = 0, std::uint64_t b = 0,
                                   std::uint64_t c = 0) noexcept;

  std::uint64_t next() noexcept {
    const std::uint64_t result = rotl(s_[0] + s_[3], 23) + s_[0];
    const std::uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl(s_[3], 45);
    return result;
  }

  // Uniform on [0, 1) with 53 random bits.
  double uniform() noexcept { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  double uniform(double lo, double hi) noexcept { return lo + (hi - lo) * uniform(); }

  // Uniform integer in [0, n), unbiased (Lemire's multiply-and-reject). n must be > 0.
  std::uint64_t below(std::uint64_t n) noexcept;

  // Standard normal. The rectangle test (~99 % of draws) is inline; the rest is out of line.
  double normal() noexcept {
    const std::uint64_t bits = next();
    const auto layer = static_cast<unsigned>(bits & 0x7F);                     // low 7 bits
    const double u = 2.0 * static_cast<double>(bits >> 11) * 0x1.0p-53 - 1.0;  // top 53 bits
    if (std::fabs(u) < detail::kZiggurat.ratio[layer]) return u * detail::kZiggurat.x[layer];
    return normal_outside_rectangle(layer, u);
  }
  // out[i] = scale * N(0, 1), i < n. Faster than n calls of normal(), and a different sequence.
  void fill_normal(double* out, std::size_t n, double scale = 1.0) noexcept;
  // out[i] += scale * N(0, 1), i < n (same draws as fill_normal).
  void add_normal(double* out, std::size_t n, double scale = 1.0) noexcept;
  // out[i] = U(lo, hi), i < n.
  void fill_uniform(double* out, std::size_t n, double lo, double hi) noexcept;

  const State& state() const noexcept { return s_; }

  // The Ziggurat's slow path (wedges and tail) for a draw that failed the rectangle test.
  double normal_outside_rectangle(unsigned layer, double u) noexcept;

 private:
  static std::uint64_t rotl(std::uint64_t x, int k) noexcept { return (x << k) | (x >> (64 - k)); }
  State s_;
};

}  // namespace qd
