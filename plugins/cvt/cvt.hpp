// The descriptor adapter "cvt" (CVT-MAP-Elites: Vassiliades, Chatzilygeroudis, Mouret, "Using
// Centroidal Voronoi Tessellations to Scale Up the Multidimensional Archive of Phenotypic Elites
// Algorithm", IEEE TEVC 2018): the archive's cells are the Voronoi cells of `cells` centroids in the
// wrapped descriptor's continuous values, instead of a grid.
//
//  * Centroids: k-means (Lloyd's algorithm) on `samples` points drawn uniformly in `bounds`, from a
//    stream of the run seed (qd::Rng(seed, kPlugin, kStreamKey, cells, samples)); the first `cells`
//    samples are the initial centroids; an empty cluster keeps its centroid; at most `iterations`
//    rounds, fewer once no sample changes cluster. A run that is being resumed (BuildContext::
//    stored_grid) reuses the centroids its run directory stores instead.
//  * describe(): the wrapped descriptor's values (written as they are to archive.csv), and the cell
//    of the nearest centroid (exact: a k-d tree that agrees with a brute-force scan, ties to the
//    lower index). A trace the wrapped descriptor cannot describe stays undescribed.
#pragma once

#include "kd_tree.hpp"

#include <qd/component.hpp>
#include <qd/config.hpp>
#include <qd/descriptor.hpp>

#include <cstdint>
#include <memory>
#include <vector>

namespace qd::cvt {

inline constexpr std::uint64_t kStreamKey = 0xC7;

inline constexpr ParamSpec kCvtParams[] = {
    param_int("cells", "1000", 1, 10000000, "number of centroids (cells of the archive)"),
    param_int("samples", "100000", 1, 1000000000, "uniform samples the centroids are fitted on (k-means), >= cells"),
    param_float_list("bounds", "[]", -kUnbounded, kUnbounded,
                     "the box the samples are drawn from: [low_0, high_0, low_1, high_1, ...], one pair per "
                     "descriptor dimension; [] = the wrapped descriptor's grid range"),
    param_int("iterations", "100", 0, 100000, "at most this many k-means rounds (0: the samples themselves)"),
};

// k-means (Lloyd) of `samples` (n × dims) from the first `k` of them; returns k × dims centroids.
std::vector<double> kmeans(const std::vector<double>& samples, std::size_t dims, std::size_t k, int iterations);

class CvtDescriptor final : public Descriptor {
 public:
  CvtDescriptor(const Config& cfg, const BuildContext& ctx);
  GridSpec grid() const override { return grid_; }
  void describe(const Trace* traces, std::size_t n, std::int64_t* cells, double* values) const override;

  bool reused_stored_centroids() const noexcept { return reused_; }

 private:
  const Descriptor* wrapped_;
  GridSpec grid_;
  std::unique_ptr<KdTree> tree_;
  bool reused_ = false;
};

}  // namespace qd::cvt
