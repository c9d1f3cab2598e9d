// Configuration, stage 3 of 3: resolution. A document (config_document.hpp) checked against the
// schema (config_schema.hpp) and the registry's components, into the Experiment a run is built
// from, with its resolved configuration as TOML (a run's config.toml). docs/design.md,
// "Configuration and planning".
#pragma once

#include "runtime/config_document.hpp"
#include "runtime/config_schema.hpp"
#include "runtime/registry.hpp"

#include <qd/config.hpp>

#include <filesystem>
#include <string>
#include <vector>

namespace qd::runtime {

// One component table after validation.
struct ComponentConfig {
  std::string table;  // "environment", "mutator", ...
  std::string type;   // component name
  const ComponentEntry* entry = nullptr;
  Config config;
  // Chosen by the environment (its default descriptor), not named in the file: the table takes no
  // keys of its own.
  bool implied = false;
};

struct Experiment {
  std::filesystem::path file;  // the experiment file (empty when built in memory)
  ExperimentSettings settings;
  ComponentConfig environment, descriptor, representation, mutator, initial;
  // [descriptor.wraps]: the descriptor a descriptor adapter (such as "cvt") wraps; table is set only
  // for an adapter (entry then always, by default the environment's own descriptor).
  ComponentConfig wrapped;
  std::string resolved_toml;              // every setting with defaults filled in
  std::vector<std::string> plugin_paths;  // [plugins] path, made absolute
  // One line each for the user (qdrun prints them as notes): keys dropped because an include or
  // --set replaced the component they were written for.
  std::vector<std::string> notes;
};

// Validates the document against the core schema and each component's declared parameters, and
// fills in every default (the environment's default descriptor included). Plugins must already be
// discovered in `registry` (component types are looked up there); no component is built.
Experiment resolve(const Document& doc, const Registry& registry);

}  // namespace qd::runtime
