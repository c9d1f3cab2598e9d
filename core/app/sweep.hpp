// qdrun sweeps: a set of experiment files times a list of seeds, run as concurrent child qdrun
// processes, skipping finished runs and resuming interrupted ones.
#pragma once

#include "runtime/registry.hpp"

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace qd::app {

struct SweepOptions {
  std::vector<std::string> experiments;
  std::vector<std::uint64_t> seeds;        // empty: each file's own experiment.seed
  std::vector<std::string> sets;           // applied to every run
  std::vector<std::string> optional_sets;  // applied where the run's component declares the key
  std::vector<std::string> plugin_paths;   // forwarded to the children
  std::string output;                      // root output directory (empty: each file's output.dir)
  long long evaluations = -1;              // budget: loops chosen per run to reach at least this
  int jobs = 0;                            // concurrent runs (0 = hardware threads)
  int workers = 0;                         // evaluation threads per run (0 = split the cores)
  bool dry_run = false;                    // plan and print, start nothing
};

// What a sweep passes a child qdrun with --planned-config: a checksum of the resolved configuration
// (runtime::Experiment::resolved_toml) it planned the run with. The child refuses to run another.
std::string planned_config_tag(const std::string& resolved_toml);

// Parses "100,200,300" (and ranges "1-5"); throws qd::InputError.
std::vector<std::uint64_t> parse_seed_list(const std::string& text);

// Validates every run (all files, all seeds) before starting any, then runs the sweep. Returns the
// process exit code: 0 when every run is complete, 1 when a run failed. Throws qd::InputError for
// bad input. `setup_registry` fills a registry the way qdrun does for one experiment.
int run_sweep(const SweepOptions& options,
              const std::function<void(runtime::Registry&, const std::vector<std::string>&)>& setup_registry);

}  // namespace qd::app
