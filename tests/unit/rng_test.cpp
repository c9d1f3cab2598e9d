#include <qd/rng.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <vector>

using qd::Rng;
using qd::Stream;

TEST(Rng, SameKeySameStreamDifferentKeyDifferentStream) {
  Rng a(42, Stream::kMutation, 3, 7), b(42, Stream::kMutation, 3, 7), c(42, Stream::kMutation, 3, 8),
      d(43, Stream::kMutation, 3, 7), e(42, Stream::kSelection, 3, 7);
  std::vector<std::uint64_t> va, vb, vc, vd, ve;
  for (int i = 0; i < 8; ++i)
    va.push_back(a.next()), vb.push_back(b.next()), vc.push_back(c.next()), vd.push_back(d.next()),
        ve.push_back(e.next());
  EXPECT_EQ(va, vb);
  EXPECT_NE(va, vc);
  EXPECT_NE(va, vd);
  EXPECT_NE(va, ve);
}

TEST(Rng, BelowStaysInRangeAndHitsEveryValue) {
  Rng r(1, Stream::kPlugin);
  std::set<std::uint64_t> seen;
  for (int i = 0; i < 10000; ++i) {
    const auto v = r.below(7);
    ASSERT_LT(v, 7u);
    seen.insert(v);
  }
  EXPECT_EQ(seen.size(), 7u);
}

TEST(Rng, NormalMomentsWithinFiveStandardErrors) {
  Rng r(5, Stream::kPlugin);
  const int n = 200000;
  std::vector<double> x(n);
  r.fill_normal(x.data(), x.size(), 2.0);
  double mean = 0, var = 0;
  for (double v : x) mean += v;
  mean /= n;
  for (double v : x) var += (v - mean) * (v - mean);
  var /= (n - 1);
  // SE(mean) = sigma/sqrt(n); SE(var) ≈ sigma^2 sqrt(2/(n-1)).
  EXPECT_NEAR(mean, 0.0, 5 * 2.0 / std::sqrt(n));
  EXPECT_NEAR(var, 4.0, 5 * 4.0 * std::sqrt(2.0 / (n - 1)));
}

TEST(Rng, UniformMeanAndBounds) {
  Rng r(9, Stream::kPlugin);
  const int n = 100000;
  double mean = 0;
  for (int i = 0; i < n; ++i) {
    const double u = r.uniform(-1.0, 1.0);
    ASSERT_GE(u, -1.0);
    ASSERT_LT(u, 1.0);
    mean += u;
  }
  EXPECT_NEAR(mean / n, 0.0, 5 * std::sqrt(1.0 / 3.0 / n));
}

TEST(Rng, NormalTailsAndKurtosisMatchTheGaussian) {
  // The Ziggurat's tail and wedge branches are rare; check them through tail mass and kurtosis.
  Rng r(17, Stream::kPlugin);
  const int n = 2000000;
  double m4 = 0, beyond3 = 0, beyond_r = 0;
  for (int i = 0; i < n; ++i) {
    const double v = r.normal();
    m4 += v * v * v * v;
    if (std::fabs(v) > 3.0) ++beyond3;
    if (std::fabs(v) > 3.442619855899) ++beyond_r;
  }
  m4 /= n;
  // E[x^4] = 3, Var[x^4] = 105 - 9 = 96.
  EXPECT_NEAR(m4, 3.0, 5 * std::sqrt(96.0 / n));
  const double p3 = 0.0026997960632601866, pr = 0.0005761085123916405;  // P(|x| > 3), P(|x| > r)
  EXPECT_NEAR(beyond3 / n, p3, 5 * std::sqrt(p3 * (1 - p3) / n));
  EXPECT_NEAR(beyond_r / n, pr, 5 * std::sqrt(pr * (1 - pr) / n));
}
