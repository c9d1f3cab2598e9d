// Experiment files: reading TOML (with includes and --set overrides), validating every table
// against its declared schema, and writing the resolved configuration back out.
#pragma once

#include "runtime/registry.hpp"

#include <qd/config.hpp>

#include <cstdint>
#include <filesystem>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace qd::runtime {

// [cost]: what `qdrun --dry-run` assumes about an environment beyond what its pilot measures
// (runtime/cost_estimate.hpp). It changes no result, so it is not part of a run's configuration:
// resolved_toml leaves it out, and a run may be resumed or swept under a file that changed it.
struct CostModel {
  // Wall time per evaluation of a mutation operator as a multiple of loop 0's, once
  // `evaluations[i]` evaluations are done: linear in between, the end values held outside; 1 when
  // empty. Episodes lengthen as an archive reaches cells that only long episodes reach; qdreport
  // measures this from finished runs ("Episode lengthening").
  std::vector<double> evaluations, offspring_time;
  double offspring_time_at(double evaluations_done) const;
};

// The core's own settings, resolved.
struct ExperimentSettings {
  std::string name;
  std::uint64_t seed = 0;
  int loops = 0;            // loop 0 (initial sampling) included
  int iterations = 0;       // MAP-Elites iterations per loop n >= 1
  int batch = 0;            // offspring per iteration
  int initial_samples = 0;  // loop-0 samples
  std::string insertion;    // "coin-flip" | "fitness"
  double replace_probability = 0.5;
  double fitness_lower_bound = std::numeric_limits<double>::quiet_NaN();  // NaN: the environment's
  std::string dataset_order;                                              // "reference" | "insertion"
  std::vector<int> hidden;
  std::string output_dir;
  int snapshot_every = 0;
  bool snapshot_parameters = true;
  int workers = 0;               // 0 = all cores
  std::string backend = "auto";  // auto | threads | processes | mpi
  double timeout_seconds = 0;
  CostModel cost;  // [cost]: read by --dry-run only
};

// One component table after validation.
struct ComponentConfig {
  std::string table;  // "environment", "mutator", ...
  std::string type;   // component name
  const ComponentEntry* entry = nullptr;
  Config config;
};

struct Experiment {
  std::filesystem::path file;  // the experiment file (empty when built in memory)
  ExperimentSettings settings;
  ComponentConfig environment, descriptor, representation, mutator, initial;
  // [descriptor.wraps]: the descriptor a descriptor adapter (such as "cvt") wraps; table is set only
  // for an adapter, and entry stays null until build_components fills in the environment's default.
  ComponentConfig wrapped;
  std::string resolved_toml;              // every setting with defaults filled in
  std::vector<std::string> plugin_paths;  // [plugins] path, made absolute
  // One line each for the user (qdrun prints them as notes): keys dropped because an include or
  // --set replaced the component they were written for.
  std::vector<std::string> notes;
};

// Raw parsed document (PIMPL around toml::table so no TOML type leaks into headers).
class Document {
 public:
  Document();
  ~Document();
  Document(Document&&) noexcept;
  Document& operator=(Document&&) noexcept;

  // Reads `file`, following `include = [...]` (paths relative to the including file; the including
  // file's keys win). Throws qd::InputError with file:line:column on any problem.
  static Document read(const std::filesystem::path& file);
  static Document parse(const std::string& text, const std::string& source_name);

  // Applies `key.path=value`; value is a TOML number, boolean, quoted string, array or inline
  // table, and anything else (a bare word, also nan, inf and dates) is taken as a string.
  // Errors name `option` (the command-line option it came from), or "--set key.path=value".
  void apply_override(const std::string& assignment, const std::string& option = {});

  // [plugins] path entries (absolute), available before plugins are loaded.
  std::vector<std::string> plugin_paths() const;
  // [plugins] search_path entries (absolute): the user directories a run searched, as its
  // config.toml records them, so that --resume finds the same plugins.
  std::vector<std::string> recorded_search_path() const;
  std::filesystem::path file() const;

  struct Impl;
  std::unique_ptr<Impl> impl;
};

// Validates the document against the core schema and each component's declared parameters.
// Plugins must already be discovered in `registry` (component types are looked up there).
Experiment resolve(const Document& doc, const Registry& registry);

// Fills `cc` with the defaults of `entry` and appends its resolved table to `ex.resolved_toml`
// (used for the descriptor chosen by the environment when the experiment names none).
void resolve_default_component(Experiment& ex, ComponentConfig& cc, const ComponentEntry& entry);

// Parameters of the core tables, for --describe and validation.
struct CoreTable {
  const char* name;
  const ParamSpec* params;
  std::size_t count;
};
std::vector<CoreTable> core_tables();

// The keys whose values differ between two resolved configurations (TOML texts), with both
// values as TOML text ("(absent)" where a key is missing), in key order.
struct ConfigDifference {
  std::string key, before, after;
};
// Throws InputError when either text is not TOML.
std::vector<ConfigDifference> config_differences(const std::string& before, const std::string& after);

// Keys --resume may change (dotted path): the budget (experiment.loops), how and where evaluations
// run ([evaluation]), what is written ([output]) and where plugins are found ([plugins]). Anything
// else would make the resumed run another experiment; experiment.name (with the seed) names the run
// directory, so a run keeps it.
bool may_change_on_resume(const std::string& key);

// Renders a component's parameters for `qdrun --describe`.
std::string describe_params(const ParamSpec* params, std::size_t count);

// `qdrun --describe` text of the tables that are no plain parameter list: [plugins] and the
// component tables ([environment], [descriptor], [representation], [mutator], [initial]). Empty
// for any other name.
std::string describe_table(const std::string& name, const Registry& registry);

// For a run directory whose components cannot all be found: one sentence per component that its
// provenance files record but `registry` does not provide (which library, where it was, and whether
// that file is gone, rejected or outside the search path). Empty when there is nothing to say.
std::string missing_plugin_hint(const std::filesystem::path& run_dir, const Registry& registry);

// For --resume, --replay and --latents: the components of `ex` (built) that would now come from
// another plugin than the one the run's newest session recorded, which happens when the library the
// run used is gone and another provides the same name (one sentence each; "" when none). A plugin
// of the same name at another path is the same plugin; one whose version changed adds a sentence to
// `notes`.
std::string changed_plugins(const std::filesystem::path& run_dir, const Experiment& ex,
                            std::vector<std::string>* notes = nullptr);

}  // namespace qd::runtime
