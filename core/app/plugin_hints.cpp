// Plugin hints for run directories (plugin_hints.hpp): read from the run's provenance files.
#include "plugin_hints.hpp"

#include "runtime/run.hpp"
#include "runtime/run_directory.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <cstdio>
#include <limits>

namespace qd::app {
namespace fs = std::filesystem;
using runtime::ComponentConfig;
using runtime::Experiment;
using runtime::kMaxTomlBytes;
using runtime::read_run_file;
using runtime::Registry;
using runtime::Rejection;
using runtime::Run;
using runtime::session_provenance;

namespace {
// The newest session's provenance (the plugins the run last loaded); empty when unreadable.
toml::table newest_provenance(const fs::path& run_dir) {
  const fs::path newest = session_provenance(run_dir, std::numeric_limits<int>::max());
  try {
    return toml::parse(read_run_file(newest, kMaxTomlBytes), newest.string());
  } catch (const std::exception&) {
    return {};
  }
}
}  // namespace

std::string changed_plugins(const fs::path& run_dir, const Experiment& ex, std::vector<std::string>* notes) {
  const toml::table prov = newest_provenance(run_dir);
  const toml::array* plugins = prov["plugins"].as_array();
  if (!plugins) return "";
  std::string out;
  std::error_code ec;
  for (const auto& node : *plugins) {
    const toml::table* p = node.as_table();
    if (!p) continue;
    const std::string table = (*p)["table"].value_or(std::string());
    const std::string plugin = (*p)["plugin"].value_or(std::string());
    const std::string version = (*p)["version"].value_or(std::string());
    const std::string path = (*p)["path"].value_or(std::string());
    const ComponentConfig* cc = nullptr;
    for (const ComponentConfig* c : {&ex.environment, &ex.descriptor, &ex.representation, &ex.mutator, &ex.initial})
      if (c->table == table) cc = c;
    if (!cc || !cc->entry || plugin.empty()) continue;
    const PluginInfo& now = *cc->entry->plugin->info;
    const std::string recorded =
        "[" + table + "] '" + cc->type + "' came from " + path + " (plugin " + plugin + " " + version + ")";
    if (plugin != now.plugin_name) {
      out += (out.empty() ? "" : "; ") + recorded + (fs::exists(path, ec) ? "" : ", which no longer exists") +
             ", but would now come from " + cc->entry->plugin->path + " (plugin " + now.plugin_name + " " +
             now.plugin_version + ")";
    } else if (notes && version != now.plugin_version) {
      notes->push_back(recorded + "; it is now version " + now.plugin_version + " (" + cc->entry->plugin->path +
                       "), which may compute otherwise");
    }
  }
  return out;
}

std::string missing_plugin_hint(const fs::path& run_dir, const Registry& registry) {
  std::error_code ec;
  const toml::table prov = newest_provenance(run_dir);
  const toml::array* plugins = prov["plugins"].as_array();
  if (!plugins) return "";
  std::string out;
  for (const auto& node : *plugins) {
    const toml::table* p = node.as_table();
    if (!p) continue;
    const std::string component = (*p)["component"].value_or(std::string());
    const std::string path = (*p)["path"].value_or(std::string());
    if (component.empty() || path.empty()) continue;
    if (registry.find(component)) continue;  // found (perhaps elsewhere): not why the run cannot start
    std::string what = "this run loaded [" + (*p)["table"].value_or(std::string()) + "] '" + component + "' from " +
                       path + " (plugin " + (*p)["plugin"].value_or(std::string()) + " " +
                       (*p)["version"].value_or(std::string()) + ")";
    const auto rejected = std::find_if(registry.rejected().begin(), registry.rejected().end(),
                                       [&](const Rejection& r) { return fs::equivalent(r.path, path, ec); });
    if (!fs::exists(path, ec)) {
      what += ", which no longer exists";
    } else if (rejected != registry.rejected().end()) {
      what += ", which is rejected now";
    } else {
      what += "; add its directory with --plugin-path";
    }
    out += (out.empty() ? "" : "; ") + what;
  }
  return out;
}

void check_same_plugins(bool quiet, const Run& run) {
  std::vector<std::string> notes;
  const std::string changed = changed_plugins(run.directory(), run.experiment(), &notes);
  if (!changed.empty())
    throw InputError(run.directory().string() + ": cannot use the plugins this run was made with: " + changed +
                     "; restore the library or add its directory with --plugin-path");
  if (!quiet)
    for (const auto& n : notes) std::fprintf(stderr, "qdrun: note: %s\n", n.c_str());
}

}  // namespace qd::app
