#include "kd_tree.hpp"

#include <qd/errors.hpp>

#include <algorithm>
#include <limits>

namespace qd::cvt {

namespace {
double squared_distance(const double* p, const double* q, std::size_t dims) noexcept {
  double d = 0.0;
  for (std::size_t k = 0; k < dims; ++k) {
    const double t = p[k] - q[k];
    d += t * t;
  }
  return d;
}
}  // namespace

std::size_t nearest_brute_force(const std::vector<double>& points, std::size_t dims, const double* q) noexcept {
  std::size_t best = 0;
  double best_d = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < points.size() / dims; ++i) {
    const double d = squared_distance(points.data() + i * dims, q, dims);
    if (d < best_d) best_d = d, best = i;
  }
  return best;
}

KdTree::KdTree(const std::vector<double>& points, std::size_t dims) : points_(points), dims_(dims) {
  QD_CHECK(dims > 0 && !points.empty() && points.size() % dims == 0 && size() < (std::size_t{1} << 31),
           "k-d tree needs a whole number of points of dims > 0 values");
  std::vector<std::uint32_t> idx(size());
  for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = static_cast<std::uint32_t>(i);
  nodes_.reserve(idx.size());
  root_ = build(idx, 0, idx.size());
}

std::int32_t KdTree::build(std::vector<std::uint32_t>& idx, std::size_t begin, std::size_t end) {
  if (begin >= end) return -1;
  // Split along the dimension of widest spread, at the median (ties by index: deterministic).
  std::size_t dim = 0;
  double widest = -1.0;
  for (std::size_t k = 0; k < dims_; ++k) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (std::size_t i = begin; i < end; ++i) {
      const double v = points_[idx[i] * dims_ + k];
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
    if (hi - lo > widest) widest = hi - lo, dim = k;
  }
  const std::size_t mid = begin + (end - begin) / 2;
  std::nth_element(idx.begin() + static_cast<std::ptrdiff_t>(begin), idx.begin() + static_cast<std::ptrdiff_t>(mid),
                   idx.begin() + static_cast<std::ptrdiff_t>(end), [&](std::uint32_t a, std::uint32_t b) {
                     const double va = points_[a * dims_ + dim], vb = points_[b * dims_ + dim];
                     return va != vb ? va < vb : a < b;
                   });
  const auto node = static_cast<std::int32_t>(nodes_.size());
  nodes_.push_back({idx[mid], static_cast<std::uint32_t>(dim), -1, -1});
  const std::int32_t left = build(idx, begin, mid);
  const std::int32_t right = build(idx, mid + 1, end);
  nodes_[static_cast<std::size_t>(node)].left = left;
  nodes_[static_cast<std::size_t>(node)].right = right;
  return node;
}

double KdTree::distance(std::size_t point, const double* q) const noexcept {
  return squared_distance(points_.data() + point * dims_, q, dims_);
}

void KdTree::search(std::int32_t n, const double* q, std::size_t& best, double& best_d) const noexcept {
  if (n < 0) return;
  const Node& node = nodes_[static_cast<std::size_t>(n)];
  const double d = distance(node.point, q);
  if (d < best_d || (d == best_d && node.point < best)) best_d = d, best = node.point;
  const double diff = q[node.dim] - points_[node.point * dims_ + node.dim];
  const std::int32_t near = diff < 0.0 ? node.left : node.right;
  const std::int32_t far = diff < 0.0 ? node.right : node.left;
  search(near, q, best, best_d);
  // The far side can hold a point at distance >= diff^2; equality matters for the index tie-break.
  if (diff * diff <= best_d) search(far, q, best, best_d);
}

std::size_t KdTree::nearest(const double* q) const noexcept {
  std::size_t best = std::numeric_limits<std::size_t>::max();
  double best_d = std::numeric_limits<double>::infinity();
  search(root_, q, best, best_d);
  return best;
}

}  // namespace qd::cvt
