// Value types shared by every interface.
#pragma once

#include <qd/export.hpp>

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

namespace qd {

// Batches are rows of a row-major matrix: row i is individual i, so one policy's parameters
// (or one latent point) are contiguous in memory.
using Matrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using Vector = Eigen::VectorXd;
using RowVector = Eigen::Matrix<double, 1, Eigen::Dynamic>;

// Outcome of one evaluation. Anything but kOk means "not inserted", never a crash.
enum class EvalStatus : std::uint8_t {
  kOk = 0,
  kInvalidAction = 1,  // the policy produced a NaN or infinite action
  kDiverged = 2,       // the simulation state became non-finite
  kFailed = 3,         // the environment reported another per-episode failure (see message)
};

QD_EXPORT const char* to_string(EvalStatus status) noexcept;

// A table of rows with a fixed number of columns, stored row-major. Used for the sub-sampled
// trajectories that descriptors read.
struct Series {
  int cols = 0;
  std::vector<double> data;

  void reset(int columns) {
    cols = columns;
    data.clear();
  }
  std::size_t rows() const noexcept { return cols == 0 ? 0 : data.size() / static_cast<std::size_t>(cols); }
  const double* row(std::size_t i) const noexcept { return data.data() + i * static_cast<std::size_t>(cols); }
  const double* last() const noexcept { return row(rows() - 1); }
  double at(std::size_t r, int c) const noexcept {
    return data[r * static_cast<std::size_t>(cols) + static_cast<std::size_t>(c)];
  }
  void truncate(std::size_t max_rows) {
    if (rows() > max_rows) data.resize(max_rows * static_cast<std::size_t>(cols));
  }
  template <class... T>
  void push(T... values) {
    static_assert(sizeof...(T) > 0);
    (data.push_back(static_cast<double>(values)), ...);
  }
};

// Everything one rollout produces. Environments fill it; descriptors read it.
struct Trace {
  EvalStatus status = EvalStatus::kOk;
  int steps = 0;            // world steps taken
  double fitness = 0.0;     // higher is better; finite; used by insertion = "fitness" only
  Series main;              // environment-defined trajectory rows (see the environment's README)
  Series aux;               // second trajectory table
  std::vector<int> events;  // environment-defined events in order (e.g. wall contacts)
  std::string message;      // why status != kOk

  void clear() {
    status = EvalStatus::kOk;
    steps = 0;
    fitness = 0.0;
    main.data.clear();
    aux.data.clear();
    events.clear();
    message.clear();
  }
};

// The behaviour grid a descriptor maps traces into. A cell index is row-major over `shape` (the
// last dimension varies fastest), so cells == the product of `shape`; every run writes this to
// grid.toml, from which plots draw the archive without knowing the descriptor.
//
// A centroidal Voronoi tessellation (CVT) instead of a grid has `centroids`: cells x dims() values,
// row-major, and a cell is the index of the nearest centroid; `shape` is then {cells}. The run
// writes them to centroids.csv (grid.toml names the file).
struct GridSpec {
  std::vector<std::int64_t> shape;   // bins per dimension ({cells} for a CVT)
  std::vector<std::string> names;    // one per descriptor dimension, for CSV headers and plots
  std::vector<double> lower, upper;  // range of the continuous values per dimension
  std::int64_t cells = 0;            // total number of cells
  std::vector<double> centroids{};   // CVT only: cells x dims(), row-major; empty for a grid
  // Optional names of the bins, for plots (the Striker's wall pairs): empty, or one list per
  // dimension, each empty (bins are numbered) or with one name per bin (grids only, not CVT). Its
  // initializer keeps a grid built as {shape, names, lower, upper, cells} free of
  // missing-initializer warnings.
  std::vector<std::vector<std::string>> labels = {};

  // Continuous values per trace (what describe() writes per trace).
  std::size_t dims() const noexcept { return names.size(); }
  bool is_cvt() const noexcept { return !centroids.empty(); }
};

}  // namespace qd
