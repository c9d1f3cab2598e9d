#include "runtime/components.hpp"

#include <qd/errors.hpp>

#include <cstdio>
#include <sstream>

namespace qd::runtime {

std::string grid_toml(const GridSpec& g) {
  std::string out = "# The behaviour grid: a cell index is row-major over shape (the last dimension fastest).\n";
  out += "cells = " + std::to_string(g.cells) + "\nshape = [";
  for (std::size_t d = 0; d < g.shape.size(); ++d) out += (d ? ", " : "") + std::to_string(g.shape[d]);
  out += "]\nnames = [";
  for (std::size_t d = 0; d < g.names.size(); ++d) out += (d ? ", " : "") + toml_string(g.names[d]);
  auto numbers = [&](const std::vector<double>& v) {
    std::string t = "[";
    for (std::size_t d = 0; d < v.size(); ++d) {
      if (d) t += ", ";
      std::ostringstream o;
      o.precision(17);
      o << v[d];
      t += o.str();
    }
    return t + "]";
  };
  out += "]\nlower = " + numbers(g.lower) + "\nupper = " + numbers(g.upper) + "\n";
  if (!g.labels.empty()) {  // names of the bins, per dimension ([] where the bins are numbered)
    out += "labels = [";
    for (std::size_t d = 0; d < g.labels.size(); ++d) {
      out += d ? ", [" : "[";
      for (std::size_t k = 0; k < g.labels[d].size(); ++k) out += (k ? ", " : "") + toml_string(g.labels[d][k]);
      out += "]";
    }
    out += "]\n";
  }
  return out;
}

std::string toml_string(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') out += '\\';
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    if (u < 0x20 || u == 0x7f) {  // TOML allows no control character in a basic string
      char esc[8];
      std::snprintf(esc, sizeof(esc), "\\u%04x", u);
      out += esc;
      continue;
    }
    out += c;
  }
  return out + "\"";
}

void check_grid(const GridSpec& g, const std::string& who) {
  const std::size_t dims = g.shape.size();
  if (g.cells <= 0 || dims == 0) throw PluginError(who + " declares an empty grid");
  if (g.names.size() != dims || g.lower.size() != dims || g.upper.size() != dims)
    throw PluginError(who + " declares a grid of " + std::to_string(dims) +
                      " dimensions with another number of names or bounds");
  std::int64_t product = 1;
  for (std::int64_t bins : g.shape) {
    if (bins <= 0 || product > g.cells) throw PluginError(who + " declares a grid dimension without bins");
    product *= bins;
  }
  if (product != g.cells)
    throw PluginError(who + " declares " + std::to_string(g.cells) + " cells, but its shape has " +
                      std::to_string(product));
  if (!g.labels.empty() && g.labels.size() != dims)
    throw PluginError(who + " declares bin labels for " + std::to_string(g.labels.size()) + " dimensions of a " +
                      std::to_string(dims) + "-dimensional grid");
  for (std::size_t d = 0; d < g.labels.size(); ++d)
    if (!g.labels[d].empty() && static_cast<std::int64_t>(g.labels[d].size()) != g.shape[d])
      throw PluginError(who + " declares " + std::to_string(g.labels[d].size()) + " bin labels for dimension " +
                        std::to_string(d) + " ('" + g.names[d] + "'), which has " + std::to_string(g.shape[d]) +
                        " bins");
}

namespace {

// Runs a factory; a ConfigError from it is reported at the key's place in the experiment file.
template <class T>
Owned<T> create(const Registry& registry, const ComponentConfig& cc, const BuildContext& ctx) {
  try {
    return registry.create<T>(*cc.entry, cc.config, ctx);
  } catch (const ConfigError& e) {
    // A key the component does not declare is no place in the experiment file: the plugin asked
    // for a parameter it never declared (a misspelt name in its code).
    if (!cc.config.has(e.key())) {
      std::string declared;
      for (const std::string& k : cc.config.keys()) declared += (declared.empty() ? "" : ", ") + k;
      throw PluginError("component '" + cc.type + "' (" + cc.entry->plugin->path + ") reads the parameter '" + e.key() +
                        "', which it does not declare (a bug in the plugin; it declares: " +
                        (declared.empty() ? std::string("nothing") : declared) + ")");
    }
    throw ConfigError(e.key(), cc.config.where(e.key()) + ": [" + cc.table + "]." + e.key() + ": " + e.what());
  }
}
}  // namespace

// A world's state lives in memory and in every checkpoint: far more than any emulated process count.
constexpr int kMaxPersistentWorlds = 1 << 16;

Components build_components(Experiment& ex, const Registry& registry) {
  Components c;
  BuildContext ctx;
  ctx.seed = ex.settings.seed;
  c.environment = create<Environment>(registry, ex.environment, ctx);
  const EnvironmentInfo info = c.environment->info();
  if (info.observation_size <= 0 || info.action_size <= 0)
    throw PluginError("environment '" + ex.environment.type + "' reports no observation or action size");
  if (info.persistent_worlds < 0 || info.persistent_worlds > kMaxPersistentWorlds)
    throw PluginError("environment '" + ex.environment.type + "' reports " + std::to_string(info.persistent_worlds) +
                      " persistent worlds (0 to " + std::to_string(kMaxPersistentWorlds) + " allowed)");
  c.shape = PolicyShape(info.observation_size, ex.settings.hidden, info.action_size);
  ctx.policy = &c.shape;

  if (!ex.descriptor.entry) {
    if (info.default_descriptor.empty())
      throw InputError("environment '" + ex.environment.type +
                       "' has no default descriptor; add [descriptor] type = ...");
    resolve_default_component(ex, ex.descriptor, registry.require(info.default_descriptor, Kind::kDescriptor));
  }
  c.descriptor = create<Descriptor>(registry, ex.descriptor, ctx);
  c.grid = c.descriptor->grid();
  check_grid(c.grid, "descriptor '" + ex.descriptor.type + "' (" + ex.descriptor.entry->plugin->path + ")");

  c.representation = create<Representation>(registry, ex.representation, ctx);
  const int latent = c.representation->latent_size();
  if (latent < 0 || static_cast<std::size_t>(latent) > c.shape.param_count())
    throw ConfigError("latent", ex.representation.config.where("latent") + ": [representation] latent size " +
                                    std::to_string(latent) + " is larger than the policy's parameter count " +
                                    std::to_string(c.shape.param_count()));
  ctx.latent_size = latent;
  c.mutator = create<Mutator>(registry, ex.mutator, ctx);
  c.initial = create<Mutator>(registry, ex.initial, ctx);
  if (c.initial->uses_parents())
    throw InputError("[initial] type = \"" + ex.initial.type +
                     "\" needs parents, but loop 0 has none; use a sampler such as \"uniform\" or \"glorot\"");
  for (const auto& [cc, obj] : {std::pair{&ex.mutator, c.mutator.get()}, std::pair{&ex.initial, c.initial.get()}})
    if (obj->needs_latent() && latent == 0)
      throw InputError("[" + cc->table + "] type = \"" + cc->type +
                       "\" needs a representation with a latent space, but [representation] type = \"" +
                       ex.representation.type + "\" has none (use \"autoencoder\" or \"pca\")");
  c.metric_names = c.mutator->metric_names();
  c.mutator_type = ex.mutator.type;
  c.initial_type = ex.initial.type;
  c.representation_type = ex.representation.type;
  auto label = [](const ComponentConfig& cc, const std::string& kind) {
    return kind + " '" + cc.type + "' (" + cc.entry->plugin->path + ")";
  };
  c.environment_label = label(ex.environment, "environment");
  c.descriptor_label = label(ex.descriptor, "descriptor");
  c.representation_label = label(ex.representation, "representation");
  c.mutator_label = label(ex.mutator, "mutator");
  c.initial_label = label(ex.initial, "initial sampler");

  for (const ComponentConfig* cc : {&ex.environment, &ex.descriptor, &ex.representation, &ex.mutator, &ex.initial}) {
    const PluginInfo& pi = *cc->entry->plugin->info;
    c.provenance.push_back("{ table = " + toml_string(cc->table) + ", component = " + toml_string(cc->type) +
                           ", plugin = " + toml_string(pi.plugin_name) + ", version = " +
                           toml_string(pi.plugin_version) + ", path = " + toml_string(cc->entry->plugin->path) + " }");
  }
  return c;
}

}  // namespace qd::runtime
