// qdrun's command line, as the app's files share it (qdrun.cpp parses it; inspect.cpp and
// sweep.cpp act on it), and the plugin search path it sets up.
#pragma once

#include "runtime/registry.hpp"

#include <string>
#include <vector>

namespace qd::app {

struct Cli {
  std::vector<std::string> experiments;
  std::vector<std::string> sets;
  std::vector<std::string> plugin_paths;
  std::string output, resume, describe, replay, svg, backend;
  long long cell = -1;
  bool cell_given = false;
  std::string seed;
  bool seed_given = false;  // else the experiment's
  int workers = 0;
  int stop_after_loop = -1;
  bool quiet = false, list = false, version = false, help = false;
  // Sweeps (several files and/or --seeds), replay of all elites, latent codes.
  std::string seeds, traces, latents;
  std::string planned_config;  // from a sweep: the checksum of the configuration it planned
  std::vector<std::string> optional_sets;
  long long evaluations = -1;
  int jobs = 0;
  bool all = false, dry_run = false;
};

// Why `dir` is no directory to search ("does not exist", "is a file", ...); empty when it is one.
std::string not_a_directory(const std::string& dir);

// Search order, first hit wins: --plugin-path, QD_PLUGIN_PATH, [plugins] path, the directories a
// run directory's config.toml recorded ([plugins] search_path, for --resume and friends), then
// qdrun's own plugin directory (<prefix>/lib/qd/plugins; the build tree's only for the qdrun that
// runs from it). Shadowed component names are reported on stderr.
void setup_registry(runtime::Registry& reg, const Cli& cli, const std::vector<std::string>& from_file,
                    const std::vector<std::string>& recorded = {});

}  // namespace qd::app
