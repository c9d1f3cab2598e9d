// The CVT adapter against brute force and the definition of k-means: lookups equal a brute-force
// nearest-centroid scan (ties included), the centroids are a fixed point of Lloyd's algorithm on
// their samples, the run seed alone decides them, a resumed run's stored centroids are reused, and
// the shipped conformance checks.
#include "cvt.hpp"

#include <qd/errors.hpp>
#include <qd/rng.hpp>
#include <qd/testing/conformance.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace {

using namespace qd;
using namespace qd::cvt;

// A wrapped descriptor that reads a trace's main row as its values (dims columns) on a coarse grid
// over [-1, 1]^dims; a trace without rows is undescribable.
class RowDescriptor final : public Descriptor {
 public:
  explicit RowDescriptor(std::size_t dims) : dims_(dims) {}
  GridSpec grid() const override {
    GridSpec g;
    for (std::size_t d = 0; d < dims_; ++d) {
      g.shape.push_back(2);
      g.names.push_back("v" + std::to_string(d));
      g.lower.push_back(-1.0);
      g.upper.push_back(1.0);
    }
    g.cells = std::int64_t{1} << dims_;
    return g;
  }
  void describe(const Trace* traces, std::size_t n, std::int64_t* cells, double* values) const override {
    for (std::size_t i = 0; i < n; ++i) {
      if (traces[i].main.rows() == 0) {
        cells[i] = -1;
        continue;
      }
      cells[i] = 0;
      for (std::size_t d = 0; d < dims_; ++d) values[i * dims_ + d] = traces[i].main.at(0, static_cast<int>(d));
    }
  }

 private:
  std::size_t dims_;
};

Config config(std::int64_t cells, std::int64_t samples) {
  Config c = defaults_of(kCvtParams, "descriptor");
  c.set_int("cells", cells);
  c.set_int("samples", samples);
  return c;
}

BuildContext context(const Descriptor& wrapped, std::uint64_t seed = 5) {
  BuildContext ctx;
  ctx.seed = seed;
  ctx.wrapped = &wrapped;
  return ctx;
}

// 20 000 random queries, and queries exactly on centroids and halfway between two (ties): the k-d
// tree gives the brute-force scan's index every time, in 1, 2, 3 and 6 dimensions.
TEST(Cvt, KdTreeLookupEqualsBruteForce) {
  for (const std::size_t dims : {1u, 2u, 3u, 6u}) {
    Rng rng(1, Stream::kPlugin, dims);
    std::vector<double> points(1000 * dims);
    for (double& v : points) v = std::round(rng.uniform(-10, 10) * 4) / 4;  // a lattice: many exact ties
    const KdTree tree(points, dims);
    std::vector<double> q(dims);
    for (int i = 0; i < 20000; ++i) {
      for (double& v : q) v = i % 3 == 0 ? std::round(rng.uniform(-11, 11) * 8) / 8 : rng.uniform(-11, 11);
      ASSERT_EQ(tree.nearest(q.data()), nearest_brute_force(points, dims, q.data()))
          << "dims " << dims << " query " << i;
    }
    for (std::size_t p = 0; p + 1 < 1000; p += 7) {
      for (std::size_t d = 0; d < dims; ++d) q[d] = 0.5 * (points[p * dims + d] + points[(p + 1) * dims + d]);
      ASSERT_EQ(tree.nearest(q.data()), nearest_brute_force(points, dims, q.data()));
      ASSERT_EQ(tree.nearest(points.data() + p * dims), nearest_brute_force(points, dims, points.data() + p * dims));
    }
  }
}

// The centroids are k-means of uniform samples in the wrapped grid's range: a fixed point of Lloyd's
// step (each centroid is the mean of the samples nearest to it), regenerated from the same stream.
TEST(Cvt, CentroidsAreAFixedPointOfLloydOnTheirSamples) {
  const RowDescriptor wrapped(2);
  Config c = config(50, 5000);
  c.set_int("iterations", 1000);
  const CvtDescriptor cvt(c, context(wrapped));
  const GridSpec g = cvt.grid();
  ASSERT_EQ(g.centroids.size(), 100u);
  EXPECT_EQ(g.shape, (std::vector<std::int64_t>{50}));
  EXPECT_EQ(g.names, (std::vector<std::string>{"v0", "v1"}));
  Rng rng(5, Stream::kPlugin, kStreamKey, 50, 5000);
  std::vector<double> samples(10000);
  for (double& v : samples) v = rng.uniform(-1.0, 1.0);
  std::vector<double> sums(100, 0.0);
  std::vector<int> counts(50, 0);
  for (std::size_t i = 0; i < 5000; ++i) {
    const std::size_t c0 = nearest_brute_force(g.centroids, 2, samples.data() + 2 * i);
    ++counts[c0];
    sums[2 * c0] += samples[2 * i];
    sums[2 * c0 + 1] += samples[2 * i + 1];
  }
  for (std::size_t k = 0; k < 50; ++k) {
    ASSERT_GT(counts[k], 0);
    EXPECT_NEAR(sums[2 * k] / counts[k], g.centroids[2 * k], 1e-12) << k;
    EXPECT_NEAR(sums[2 * k + 1] / counts[k], g.centroids[2 * k + 1], 1e-12) << k;
  }
  // Uniform samples give cells of about equal area: no cell holds more than three times its share.
  for (int n : counts) EXPECT_LT(n, 3 * 5000 / 50);
}

// describe() = the wrapped values, unchanged, and the brute-force nearest centroid; undescribable
// traces stay undescribed.
TEST(Cvt, DescribeIsTheNearestCentroidOfTheWrappedValues) {
  const RowDescriptor wrapped(3);
  const CvtDescriptor cvt(config(200, 4000), context(wrapped));
  const GridSpec g = cvt.grid();
  Rng rng(2, Stream::kPlugin);
  std::vector<Trace> traces(500);
  for (std::size_t i = 0; i < traces.size(); ++i) {
    traces[i].main.reset(3);
    if (i % 50 != 0) traces[i].main.push(rng.uniform(-1.5, 1.5), rng.uniform(-1.5, 1.5), rng.uniform(-1.5, 1.5));
  }
  std::vector<std::int64_t> cells(traces.size());
  std::vector<double> values(3 * traces.size());
  cvt.describe(traces.data(), traces.size(), cells.data(), values.data());
  for (std::size_t i = 0; i < traces.size(); ++i) {
    if (i % 50 == 0) {
      EXPECT_EQ(cells[i], -1);
      continue;
    }
    for (int d = 0; d < 3; ++d) EXPECT_EQ(values[3 * i + static_cast<std::size_t>(d)], traces[i].main.at(0, d));
    EXPECT_EQ(static_cast<std::size_t>(cells[i]), nearest_brute_force(g.centroids, 3, values.data() + 3 * i));
  }
}

// The run seed decides the centroids; a resumed run's stored centroids (same cells, dimensions and
// bounds) are used as they are, anything else is computed afresh; bounds replace the wrapped range.
TEST(Cvt, SeedAndStoredGridDecideTheCentroids) {
  const RowDescriptor wrapped(2);
  const GridSpec a = CvtDescriptor(config(30, 300), context(wrapped, 5)).grid();
  EXPECT_EQ(a.centroids, CvtDescriptor(config(30, 300), context(wrapped, 5)).grid().centroids);
  EXPECT_NE(a.centroids, CvtDescriptor(config(30, 300), context(wrapped, 6)).grid().centroids);

  GridSpec stored = a;
  stored.centroids[0] = 0.123;  // distinguishable from anything k-means gives
  BuildContext ctx = context(wrapped, 5);
  ctx.stored_grid = &stored;
  const CvtDescriptor resumed(config(30, 300), ctx);
  EXPECT_TRUE(resumed.reused_stored_centroids());
  EXPECT_EQ(resumed.grid().centroids, stored.centroids);
  const CvtDescriptor other(config(31, 300), ctx);
  EXPECT_FALSE(other.reused_stored_centroids());

  Config bounded = config(30, 300);
  bounded.set_float_list("bounds", {0.0, 10.0, -5.0, 5.0});
  const GridSpec b = CvtDescriptor(bounded, context(wrapped)).grid();
  EXPECT_EQ(b.lower, (std::vector<double>{0.0, -5.0}));
  EXPECT_EQ(b.upper, (std::vector<double>{10.0, 5.0}));
  for (std::size_t k = 0; k < 30; ++k) EXPECT_TRUE(b.centroids[2 * k] >= 0.0 && b.centroids[2 * k] <= 10.0);
}

TEST(Cvt, ConfigurationErrorsNameTheKey) {
  const RowDescriptor wrapped(2);
  try {
    CvtDescriptor(config(100, 10), context(wrapped));
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.key(), "samples");
  }
  Config c = config(10, 100);
  c.set_float_list("bounds", {0.0, 1.0});
  try {
    CvtDescriptor(c, context(wrapped));
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.key(), "bounds");
    EXPECT_NE(std::string(e.what()).find("give 4"), std::string::npos) << e.what();
  }
  EXPECT_THROW(CvtDescriptor(config(10, 100), BuildContext{}), InputError);
}

TEST(Cvt, Conforms) {
  const RowDescriptor wrapped(2);
  const CvtDescriptor cvt(config(64, 2000), context(wrapped));
  Rng rng(3, Stream::kPlugin);
  std::vector<Trace> traces(100);
  for (Trace& t : traces) {
    t.main.reset(2);
    t.main.push(rng.uniform(-1, 1), rng.uniform(-1, 1));
  }
  const qd::testing::Report report = qd::testing::check_descriptor(cvt, traces);
  EXPECT_TRUE(report.ok()) << report;
}

}  // namespace
