// Building an experiment's components: every plugin factory runs here, and the components are
// checked against each other (sizes, grid, latent space) before anything touches the disk.
// Sweeps use this to validate every file before any run starts.
#pragma once

#include "runtime/experiment.hpp"
#include "runtime/registry.hpp"

#include <qd/descriptor.hpp>
#include <qd/environment.hpp>
#include <qd/mutator.hpp>
#include <qd/policy.hpp>
#include <qd/representation.hpp>

#include <filesystem>
#include <limits>
#include <string>
#include <vector>

namespace qd::runtime {

struct Components {
  PolicyShape shape;
  GridSpec grid;
  Owned<Environment> environment;
  Owned<Descriptor> wrapped;     // the descriptor a descriptor adapter wraps (null without an adapter)
  Owned<Descriptor> descriptor;  // destroyed before `wrapped`, which it points to
  Owned<Representation> representation;
  Owned<Mutator> mutator;                                       // loops n >= 1
  Owned<Mutator> initial;                                       // loop 0
  std::string mutator_type, initial_type, representation_type;  // component names, for messages
  std::vector<std::string> metric_names;                        // the mutator's extra metrics.csv columns
  // The task's fitness (EnvironmentInfo): whether there is one, and the lower bound of qd_score
  // ([experiment] fitness_lower_bound, else the environment's; NaN when neither gives one).
  bool has_fitness = false;
  double fitness_lower_bound = std::numeric_limits<double>::quiet_NaN();
  // How messages name each component: "mutator 'iso' (/path/qd_basic.so)".
  std::string environment_label = "the environment", descriptor_label = "the descriptor",
              representation_label = "the representation", mutator_label = "the mutator",
              initial_label = "the initial sampler";
  // One TOML inline table per component (table, component, plugin, version, path), for provenance.
  std::vector<std::string> provenance;
};

// Throws qd::InputError / ConfigError / PluginError naming the file, key or plugin. `ex` is
// resolved completely (resolve() chose every default). `stored_grid`: the grid of an existing run being opened, for
// descriptors that compute their grid (BuildContext::stored_grid).
Components build_components(const Experiment& ex, const Registry& registry, const GridSpec* stored_grid = nullptr);

// grid.toml: the grid's kind ("grid" or "cvt"), cells, shape, names and bounds, its bins' labels if
// it names them; a CVT's also names its centroids file, centroids.csv (centroids_csv()), with the
// file's CRC-32C.
std::string grid_toml(const GridSpec& grid);
// centroids.csv of a CVT grid: `centroid,<name>...`, one row per cell, every value round-tripping.
std::string centroids_csv(const GridSpec& grid);
// The grid a run directory stores (grid.toml, and a CVT's centroids.csv checked against its
// CRC-32C). Returns false when the directory has no grid.toml; throws StateError for a damaged one.
bool read_stored_grid(const std::filesystem::path& run_dir, GridSpec& grid);
// Throws PluginError naming `who` for a grid that breaks the descriptor contract: cells not the
// product of the shape, names or bounds missing, bin labels of another count than the bins, a CVT's
// centroids of the wrong count or not finite.
void check_grid(const GridSpec& grid, const std::string& who);

}  // namespace qd::runtime
