#include "runtime/number_format.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

namespace qd::runtime {
namespace {

using u64 = std::uint64_t;
__extension__ using u128 = unsigned __int128;  // GCC and Clang on 64-bit targets

// Decimal exponents k of the scaled values v * 10^-k, from the smallest subnormal (-324) to the
// largest double (292).
constexpr int kMinK = -324, kMaxK = 292;

struct Power {
  u64 hi, lo;  // G = floor(10^-k * 2^(127 - e)) + 1, so 2^127 < G <= 2^128 - 1
  int e;       // floor(log2(10^-k))
};

// Little-endian base-2^32 naturals: just enough to compute the table exactly, once.
using Big = std::vector<std::uint32_t>;

void mul_small(Big& a, std::uint32_t m) {
  u64 carry = 0;
  for (auto& w : a) {
    const u64 t = static_cast<u64>(w) * m + carry;
    w = static_cast<std::uint32_t>(t);
    carry = t >> 32;
  }
  if (carry) a.push_back(static_cast<std::uint32_t>(carry));
}

void div_small(Big& a, std::uint32_t d) {  // a = floor(a / d)
  u64 rem = 0;
  for (std::size_t i = a.size(); i-- > 0;) {
    const u64 t = (rem << 32) | a[i];
    a[i] = static_cast<std::uint32_t>(t / d);
    rem = t % d;
  }
  while (!a.empty() && a.back() == 0) a.pop_back();
}

int bit_length(const Big& a) {
  return a.empty() ? 0 : static_cast<int>(32 * (a.size() - 1)) + (32 - __builtin_clz(a.back()));
}

Big power_of_ten(int n) {
  Big p{1};
  for (int i = 0; i < n; ++i) mul_small(p, 10);
  return p;
}

// Bits [shift, shift + 128) of a (shift >= 0), or a * 2^-shift (shift < 0), as 128 bits.
u128 bits_from(const Big& a, int shift) {
  u128 r = 0;
  for (int bit = 0; bit < 128; ++bit) {
    const int src = bit + shift;
    if (src < 0) continue;
    const auto word = static_cast<std::size_t>(src / 32);
    if (word < a.size() && ((a[word] >> (src % 32)) & 1u)) r |= u128{1} << bit;
  }
  return r;
}

const std::array<Power, kMaxK - kMinK + 1>& powers() {
  static const auto table = [] {
    std::array<Power, kMaxK - kMinK + 1> t{};
    for (int k = kMinK; k <= kMaxK; ++k) {
      u128 g;
      int e;
      if (k <= 0) {  // 10^-k is an integer: its leading 128 bits
        const Big p = power_of_ten(-k);
        e = bit_length(p) - 1;
        g = bits_from(p, e - 127);
      } else {
        // 10^k is not a power of two, so floor(log2 10^-k) = -bitlen(10^k). The quotient
        // 2^(127 - e) / 10^k = 2^(127 - e - k) / 5^k is floored one division by 5 at a time
        // (floor(floor(a / b) / c) = floor(a / (b c))).
        e = -bit_length(power_of_ten(k));
        const int n = 127 - e - k;
        Big q(static_cast<std::size_t>(n / 32 + 1), 0);
        q.back() = std::uint32_t{1} << (n % 32);
        for (int i = 0; i < k; ++i) div_small(q, 5);
        g = bits_from(q, 0);
      }
      g += 1;
      t[static_cast<std::size_t>(k - kMinK)] = {static_cast<u64>(g >> 64), static_cast<u64>(g), e};
    }
    return t;
  }();
  return table;
}

// floor(G cp / 2^128), with its lowest bit set when the product has a fraction (round to odd).
// G exceeds the exact 10^-k 2^(127 - e) by at most 1, so G cp / 2^128 exceeds the exact value x
// by less than cp / 2^128 < 2^-64. If the middle 64 bits of the product are not all zero its
// fraction is at least 2^-64: then x is not an integer and has the same floor, and the result is
// exact. Otherwise x may be an integer or lie just below one: returns false.
bool round_to_odd(const Power& g, u64 cp, u64& out) {
  const u128 lo = static_cast<u128>(g.lo) * cp;
  const u128 hi = static_cast<u128>(g.hi) * cp;
  const u128 upper = hi + (lo >> 64);  // bits 64..191 of the product
  if (static_cast<u64>(upper) == 0) return false;
  out = static_cast<u64>(upper >> 64) | 1;
  return true;
}

// The shortest decimal d 10^k in the rounding interval of v = c 2^q, the nearest to v among the
// shortest (what std::to_chars prints). False when undecided.
bool shortest(u64 c, int q, bool irregular, u64& d, int& k) {
  // k = floor(log10 2^q), or floor(log10 (3/4 2^q)) when the interval below v is half as wide.
  // Then the interval is at least 1 and less than 10 units of 10^k wide.
  k = detail::floor_log10_pow2(q, irregular);
  const Power& g = powers()[static_cast<std::size_t>(k - kMinK)];
  // Everything in units of 2^(q - 2): v is cb, the interval [cbl, cbr]. Scaled by 10^-k these
  // become vb, vbl, vbr = 4 v 10^-k etc.; h in 1..4 aligns cb 2^q 10^-k with G's 2^(e - 127).
  const int h = q + g.e + 1;
  const u64 cb = c << 2;
  const u64 cbl = irregular ? cb - 1 : cb - 2;
  const u64 cbr = cb + 2;
  u64 vb, vbl, vbr;
  if (!round_to_odd(g, cb << h, vb) || !round_to_odd(g, cbl << h, vbl) || !round_to_odd(g, cbr << h, vbr)) return false;
  // Here vb, vbl and vbr are odd (inexact) and every candidate times 4 is even, so no value meets
  // an interval end and no tie between two candidates is possible: both would need an exact
  // scaled value, which took the fallback. No branches: which candidate wins is close to random.
  const u64 s = vb >> 2, t = s + 1;
  const bool s_in = vbl < s << 2;
  const bool t_in = t << 2 < vbr;
  const bool t_nearer = vb > (s << 2) + 2;
  d = s + static_cast<u64>(!s_in || (t_in && t_nearer));
  // A multiple of 10 in the interval is shorter still; at most one fits (the interval is
  // narrower than 10 units) and it is either of these.
  const u64 sp10 = 10 * (s / 10), tp10 = sp10 + 10;
  const bool sp10_in = vbl < sp10 << 2;
  const bool tp10_in = tp10 << 2 < vbr;
  const bool ten = sp10_in != tp10_in;
  d = ten ? (sp10_in ? sp10 : tp10) / 10 : d;
  k += ten;
  // Only that multiple can have more zeros: s or t ending in 0 would be sp10 or tp10.
  while (d % 10 == 0) {
    d /= 10;
    ++k;
  }
  return true;
}

constexpr char kDigitPairs[] =
    "00010203040506070809101112131415161718192021222324252627282930313233343536373839"
    "40414243444546474849505152535455565758596061626364656667686970717273747576777879"
    "8081828384858687888990919293949596979899";

void write_pair(unsigned x, char* out) {
  std::memcpy(out, kDigitPairs + 2 * x, 2);
}

// The 8 digits of x < 10^8 at out[0..8).
void write8(std::uint32_t x, char* out) {
  const std::uint32_t hi = x / 10000, lo = x % 10000;
  write_pair(hi / 100, out);
  write_pair(hi % 100, out + 2);
  write_pair(lo / 100, out + 4);
  write_pair(lo % 100, out + 6);
}

constexpr std::array<u64, 20> kPow10 = [] {
  std::array<u64, 20> p{};
  p[0] = 1;
  for (std::size_t i = 1; i < p.size(); ++i) p[i] = p[i - 1] * 10;
  return p;
}();

int digit_count(u64 d) {  // d >= 1
  const int bits = 64 - __builtin_clzll(d);
  const int guess = (bits * 1233) >> 12;  // about bits log10 2: the count is guess or guess + 1
  return guess + (d >= kPow10[static_cast<std::size_t>(guess)]);
}

char* fallback(double v, char* out) {
  return std::to_chars(out, out + kNumberBufferBytes, v).ptr;
}

}  // namespace

namespace detail {
int floor_log10_pow2(int q, bool three_quarters) noexcept {
  // log10 2 and -log10 3/4 in units of 2^-41, rounded.
  return static_cast<int>((static_cast<std::int64_t>(q) * 661971961083 - (three_quarters ? 274743187321 : 0)) >> 41);
}
}  // namespace detail

char* write_number(double v, char* out) noexcept {
  u64 bits;
  std::memcpy(&bits, &v, sizeof(bits));
  const u64 mantissa = bits & ((u64{1} << 52) - 1);
  const int biased = static_cast<int>((bits >> 52) & 0x7ff);
  if (biased == 0x7ff) {
    if (mantissa != 0) {
      std::memcpy(out, "nan", 3);
      return out + 3;
    }
    return fallback(v, out);  // "inf", "-inf"
  }
  if (biased == 0 && mantissa == 0) return fallback(v, out);  // "0", "-0"
  char* const first = out;
  *out = '-';
  out += bits >> 63;
  const u64 c = biased ? mantissa | (u64{1} << 52) : mantissa;
  const int q = biased ? biased - 1075 : -1074;
  u64 d;
  int k;
  if (!shortest(c, q, mantissa == 0 && biased > 1, d, k)) return fallback(v, first);

  // The digits at digits[0..n), followed by enough bytes for the fixed-size copies below (a
  // copy of n bytes would be a call). d < 2^53 10 < 10^17, so d / 10^8 has one digit.
  char buf[48];
  const u64 hi = d / 100000000, lo = d % 100000000;
  buf[7] = static_cast<char>('0' + hi / 100000000);
  write8(static_cast<std::uint32_t>(hi % 100000000), buf + 8);
  write8(static_cast<std::uint32_t>(lo), buf + 16);
  const int n = digit_count(d);
  const char* digits = buf + 24 - n;

  // As std::to_chars: fixed or scientific notation, whichever is shorter, fixed on a tie.
  const int e = k + n - 1;  // v = d1.d2...dn 10^e
  const int sci_length = n + (n > 1) + 2 + (e <= -100 || e >= 100 ? 3 : 2);
  const int fixed_length = k >= 0 ? n + k : (n + k > 0 ? n + 1 : 2 - k);
  if (fixed_length <= sci_length) {
    // to_chars prints an integer's exact digits, which are not the shortest beyond 2^53.
    if (k > 0) return fallback(v, first);
    if (k == 0) {
      std::memcpy(out, digits, 24);
      return out + n;
    }
    const int point = n + k;
    if (point > 0) {  // d1..d_point . the rest
      std::memcpy(out, digits, 24);
      out[point] = '.';
      std::memcpy(out + point + 1, digits + point, 24);
      return out + n + 1;
    }
    std::memset(out, '0', 8);  // "0." and at most 3 zeros: with more, scientific is shorter
    out[1] = '.';
    std::memcpy(out + 2 - point, digits, 24);
    return out + 2 - k;
  }
  out[0] = digits[0];
  out[1] = '.';
  std::memcpy(out + 2, digits + 1, 24);
  out += n > 1 ? n + 1 : 1;
  *out++ = 'e';
  *out++ = e < 0 ? '-' : '+';
  const int exponent = e < 0 ? -e : e;
  if (exponent >= 100) *out++ = static_cast<char>('0' + exponent / 100);
  write_pair(static_cast<unsigned>(exponent % 100), out);
  return out + 2;
}

}  // namespace qd::runtime
