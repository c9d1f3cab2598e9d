#include "runtime/number_format.hpp"

#include <qd/rng.hpp>

#include <gtest/gtest.h>

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string>

using qd::runtime::kNumberBufferBytes;
using qd::runtime::write_number;

namespace {

std::string ours(double v) {
  char buf[kNumberBufferBytes];
  return std::string(buf, write_number(v, buf));
}

std::string reference(double v) {
  char buf[kNumberBufferBytes];
  return std::string(buf, std::to_chars(buf, buf + sizeof(buf), v).ptr);
}

// Counts values whose text differs from std::to_chars' (printing the first few).
class Comparison {
 public:
  void check(double v) {
    ++checked_;
    const std::string a = ours(v), b = reference(v);
    if (a != b && ++mismatches_ <= 10) ADD_FAILURE() << std::hexfloat << v << ": wrote " << a << ", to_chars " << b;
  }
  // v, -v and their three nearest neighbours on each side.
  void check_around(double v) {
    for (double x : {v, -v}) {
      check(x);
      double below = x, above = x;
      for (int i = 0; i < 3; ++i) {
        below = std::nextafter(below, -std::numeric_limits<double>::infinity());
        above = std::nextafter(above, std::numeric_limits<double>::infinity());
        check(below);
        check(above);
      }
    }
  }
  long checked() const { return checked_; }
  long mismatches() const { return mismatches_; }

 private:
  long checked_ = 0, mismatches_ = 0;
};

}  // namespace

TEST(NumberFormat, SpecialValuesAsPandasReadsThem) {
  EXPECT_EQ(ours(0.0), "0");
  EXPECT_EQ(ours(-0.0), "-0");
  EXPECT_EQ(ours(std::numeric_limits<double>::infinity()), "inf");
  EXPECT_EQ(ours(-std::numeric_limits<double>::infinity()), "-inf");
  EXPECT_EQ(ours(std::nan("")), "nan");
  EXPECT_EQ(ours(-std::nan("")), "nan");
}

TEST(NumberFormat, HandPickedValuesInBothNotations) {
  EXPECT_EQ(ours(0.1), "0.1");
  EXPECT_EQ(ours(-1.0 / 3.0), "-0.3333333333333333");
  EXPECT_EQ(ours(0.7853981633974483), "0.7853981633974483");
  EXPECT_EQ(ours(123.456), "123.456");
  EXPECT_EQ(ours(1e22), "1e+22");
  EXPECT_EQ(ours(1e-7), "1e-07");
  EXPECT_EQ(ours(0.001), "0.001");  // a tie in length: fixed
  EXPECT_EQ(ours(1.5e-4), "0.00015");
  EXPECT_EQ(ours(6.02214076e23), "6.02214076e+23");
  EXPECT_EQ(ours(5e-324), "5e-324");  // the smallest subnormal
  EXPECT_EQ(ours(std::numeric_limits<double>::max()), "1.7976931348623157e+308");
  EXPECT_EQ(ours(std::numeric_limits<double>::min()), "2.2250738585072014e-308");
  EXPECT_EQ(ours(72057594037927936.0), "72057594037927936");  // 2^56: exact integer digits
}

TEST(NumberFormat, DecimalExponentOfEveryBinaryExponent) {
  for (int q = -1074; q <= 971; ++q) {
    const long double x = static_cast<long double>(q) * std::log10(2.0L);
    ASSERT_EQ(qd::runtime::detail::floor_log10_pow2(q, false), static_cast<int>(std::floor(x))) << q;
    ASSERT_EQ(qd::runtime::detail::floor_log10_pow2(q, true), static_cast<int>(std::floor(x + std::log10(0.75L)))) << q;
  }
}

// Every binary exponent, with the significands at the interval's irregular edge (powers of two)
// and around them: each table entry and both interval shapes.
TEST(NumberFormat, MatchesToCharsAroundEveryPowerOfTwo) {
  Comparison c;
  for (int q = -1074; q <= 1023; ++q) c.check_around(std::ldexp(1.0, q));
  EXPECT_EQ(c.mismatches(), 0) << "of " << c.checked();
}

// Values near short decimals, where v 10^-k is (nearly) an integer: the undecided cases and the
// ties between two shortest candidates.
TEST(NumberFormat, MatchesToCharsAroundShortDecimalsAndIntegers) {
  Comparison c;
  for (int k = -325; k <= 309; ++k)
    for (int m = 1; m < 100; ++m)
      c.check_around(std::strtod((std::to_string(m) + "e" + std::to_string(k)).c_str(), nullptr));
  for (long i = 1; i < 200000; ++i) c.check_around(static_cast<double>(i));
  for (int j = 1; j <= 17; ++j)
    for (long i = 0; i < 20000; ++i) c.check(static_cast<double>(i) / std::pow(10.0, j));
  for (long i = 1; i < 200000; ++i) c.check(std::ldexp(static_cast<double>(i), -1074));  // subnormals
  EXPECT_EQ(c.mismatches(), 0) << "of " << c.checked();
}

TEST(NumberFormat, MatchesToCharsOnRandomDoubles) {
  Comparison c;
  qd::Rng rng(7, qd::Stream::kPlugin, 0);
  for (int i = 0; i < 1000000; ++i) {
    const std::uint64_t bits = rng.next();
    double v;
    std::memcpy(&v, &bits, sizeof(v));
    if (std::isfinite(v)) c.check(v);
    c.check(rng.uniform() * 2.0 - 1.0);  // the usual policy parameter
  }
  EXPECT_EQ(c.mismatches(), 0) << "of " << c.checked();
}

TEST(NumberFormat, EveryTextReadsBackToItsDouble) {
  qd::Rng rng(8, qd::Stream::kPlugin, 0);
  for (int i = 0; i < 100000; ++i) {
    const std::uint64_t bits = rng.next();
    double v;
    std::memcpy(&v, &bits, sizeof(v));
    if (!std::isfinite(v)) continue;
    const std::string text = ours(v);
    double back = 0;
    const auto r = std::from_chars(text.data(), text.data() + text.size(), back);
    ASSERT_EQ(r.ptr, text.data() + text.size()) << text;
    ASSERT_EQ(std::memcmp(&back, &v, sizeof(v)), 0) << text;
  }
}
