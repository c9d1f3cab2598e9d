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

#include <string>
#include <vector>

namespace qd::runtime {

struct Components {
  PolicyShape shape;
  GridSpec grid;
  Owned<Environment> environment;
  Owned<Descriptor> descriptor;
  Owned<Representation> representation;
  Owned<Mutator> mutator;                                       // loops n >= 1
  Owned<Mutator> initial;                                       // loop 0
  std::string mutator_type, initial_type, representation_type;  // component names, for messages
  std::vector<std::string> metric_names;                        // the mutator's extra metrics.csv columns
  // How messages name each component: "mutator 'iso' (/path/qd_basic.so)".
  std::string environment_label = "the environment", descriptor_label = "the descriptor",
              representation_label = "the representation", mutator_label = "the mutator",
              initial_label = "the initial sampler";
  // One TOML inline table per component (table, component, plugin, version, path), for provenance.
  std::vector<std::string> provenance;
};

// Throws qd::InputError / ConfigError / PluginError naming the file, key or plugin. Resolves the
// environment's default descriptor into `ex` when the experiment names none.
Components build_components(Experiment& ex, const Registry& registry);

// grid.toml: the grid's cells, shape, names and bounds, and its bins' labels if it names them.
std::string grid_toml(const GridSpec& grid);
// Throws PluginError naming `who` for a grid that breaks the descriptor contract: cells not the
// product of the shape, names or bounds missing, bin labels of another count than the bins.
void check_grid(const GridSpec& grid, const std::string& who);

// `s` quoted as a TOML basic string.
std::string toml_string(const std::string& s);

}  // namespace qd::runtime
