#include "cvt.hpp"

#include <qd/errors.hpp>
#include <qd/rng.hpp>

#include <cmath>
#include <string>

namespace qd::cvt {

std::vector<double> kmeans(const std::vector<double>& samples, std::size_t dims, std::size_t k, int iterations) {
  const std::size_t n = samples.size() / dims;
  QD_CHECK(k >= 1 && k <= n, "k-means needs at least as many samples as centroids");
  std::vector<double> centroids(samples.begin(), samples.begin() + static_cast<std::ptrdiff_t>(k * dims));
  std::vector<std::size_t> assigned(n, k);  // k = not assigned yet
  std::vector<double> sums(k * dims);
  std::vector<std::size_t> counts(k);
  for (int it = 0; it < iterations; ++it) {
    const KdTree tree(centroids, dims);
    bool changed = false;
    std::fill(sums.begin(), sums.end(), 0.0);
    std::fill(counts.begin(), counts.end(), 0);
    for (std::size_t i = 0; i < n; ++i) {
      const double* x = samples.data() + i * dims;
      const std::size_t c = tree.nearest(x);
      changed = changed || c != assigned[i];
      assigned[i] = c;
      ++counts[c];
      for (std::size_t d = 0; d < dims; ++d) sums[c * dims + d] += x[d];
    }
    if (!changed) break;
    for (std::size_t c = 0; c < k; ++c)
      if (counts[c] > 0)
        for (std::size_t d = 0; d < dims; ++d)
          centroids[c * dims + d] = sums[c * dims + d] / static_cast<double>(counts[c]);
  }
  return centroids;
}

CvtDescriptor::CvtDescriptor(const Config& cfg, const BuildContext& ctx) : wrapped_(ctx.wrapped) {
  if (wrapped_ == nullptr)
    throw InputError(
        "descriptor 'cvt' wraps another descriptor, but none was given (the core passes "
        "[descriptor.wraps], or the environment's own descriptor)");
  const GridSpec inner = wrapped_->grid();
  const std::size_t dims = inner.dims();
  const auto cells = static_cast<std::size_t>(cfg.get_int("cells"));
  const auto samples = static_cast<std::size_t>(cfg.get_int("samples"));
  if (samples < cells)
    throw ConfigError("samples", "samples = " + std::to_string(samples) + " must be at least cells = " +
                                     std::to_string(cells) + " (k-means starts from the first `cells` samples)");
  std::vector<double> lower = inner.lower, upper = inner.upper;
  const std::vector<double> bounds = cfg.get_float_list("bounds");
  if (!bounds.empty()) {
    if (bounds.size() != 2 * dims)
      throw ConfigError("bounds", "bounds has " + std::to_string(bounds.size()) +
                                      " values; the wrapped descriptor has " + std::to_string(dims) +
                                      " dimensions, so give " + std::to_string(2 * dims) +
                                      " (low_0, high_0, low_1, high_1, ...)");
    for (std::size_t d = 0; d < dims; ++d) lower[d] = bounds[2 * d], upper[d] = bounds[2 * d + 1];
  }
  for (std::size_t d = 0; d < dims; ++d)
    if (!(std::isfinite(lower[d]) && std::isfinite(upper[d]) && lower[d] < upper[d]))
      throw ConfigError("bounds", "dimension " + std::to_string(d) + " has the range [" + std::to_string(lower[d]) +
                                      ", " + std::to_string(upper[d]) + "]; each needs low < high, both finite");

  grid_.shape = {static_cast<std::int64_t>(cells)};
  grid_.names = inner.names;
  grid_.lower = lower;
  grid_.upper = upper;
  grid_.cells = static_cast<std::int64_t>(cells);
  const GridSpec* stored = ctx.stored_grid;
  if (stored && stored->is_cvt() && stored->cells == grid_.cells && stored->dims() == dims && stored->lower == lower &&
      stored->upper == upper) {
    grid_.centroids = stored->centroids;  // the resumed run's own cells, exactly
    reused_ = true;
  } else {
    Rng rng(ctx.seed, Stream::kPlugin, kStreamKey, cells, samples);
    std::vector<double> points(samples * dims);
    for (std::size_t i = 0; i < samples; ++i)
      for (std::size_t d = 0; d < dims; ++d) points[i * dims + d] = rng.uniform(lower[d], upper[d]);
    grid_.centroids = kmeans(points, dims, cells, static_cast<int>(cfg.get_int("iterations")));
  }
  tree_ = std::make_unique<KdTree>(grid_.centroids, dims);
}

void CvtDescriptor::describe(const Trace* traces, std::size_t n, std::int64_t* cells, double* values) const {
  wrapped_->describe(traces, n, cells, values);
  const std::size_t dims = grid_.dims();
  for (std::size_t i = 0; i < n; ++i) {
    if (cells[i] < 0) continue;
    const double* v = values + i * dims;
    bool finite = true;
    for (std::size_t d = 0; d < dims; ++d) finite = finite && std::isfinite(v[d]);
    // A non-finite value has no nearest centroid; the core reports it and makes the evaluation invalid.
    cells[i] = finite ? static_cast<std::int64_t>(tree_->nearest(v)) : 0;
  }
}

}  // namespace qd::cvt
