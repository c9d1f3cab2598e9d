#include "runtime/components.hpp"

#include "runtime/checkpoint.hpp"
#include "runtime/number_text.hpp"
#include "runtime/run_files.hpp"

#include <qd/errors.hpp>

#include <toml++/toml.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

namespace qd::runtime {
namespace fs = std::filesystem;

namespace {
// What a run's grid.toml and centroids.csv can hold at most (the largest CVT, 10^7 cells, writes
// about 2.5 GB of centroids in 10 dimensions): more is not a file qdrun wrote.
constexpr std::uint64_t kMaxGridTomlBytes = std::uint64_t{16} << 20;
constexpr std::uint64_t kMaxCentroidsBytes = std::uint64_t{4} << 30;
}  // namespace

std::string centroids_csv(const GridSpec& g) {
  const std::size_t dims = g.dims();
  std::string out = "centroid";
  for (const std::string& name : g.names) out += "," + name;
  out += '\n';
  for (std::size_t c = 0; dims > 0 && c < g.centroids.size() / dims; ++c) {
    append_int(out, static_cast<std::int64_t>(c));
    for (std::size_t d = 0; d < dims; ++d) {
      out += ',';
      append_number(out, g.centroids[c * dims + d]);
    }
    out += '\n';
  }
  return out;
}

std::string grid_toml(const GridSpec& g) {
  std::string out =
      g.is_cvt() ? "# The behaviour space: a centroidal Voronoi tessellation. A cell is the index of the nearest\n"
                   "# centroid (Euclidean, in the descriptor's values); the centroids are in `centroids`, one row\n"
                   "# per cell. shape = [cells].\n"
                 : "# The behaviour grid: a cell index is row-major over shape (the last dimension fastest).\n";
  out += std::string("kind = \"") + (g.is_cvt() ? "cvt" : "grid") + "\"\n";
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
  if (g.is_cvt()) {
    const std::string csv = centroids_csv(g);
    char crc[16];
    std::snprintf(crc, sizeof(crc), "%08x", crc32c(csv.data(), csv.size()));
    out += "centroids = \"centroids.csv\"\ncentroids_crc32c = \"" + std::string(crc) + "\"\n";
  }
  return out;
}

bool read_stored_grid(const fs::path& run_dir, GridSpec& g) {
  const fs::path file = run_dir / "grid.toml";
  if (!exists_nofollow(file)) return false;
  // Files of the run directory: regular, read without blocking and only up to what they can hold
  // (a FIFO or a symlink to /dev/zero there is refused, StateError).
  toml::table t;
  try {
    t = toml::parse(read_run_file(file, kMaxGridTomlBytes), file.string());
  } catch (const toml::parse_error& e) {
    throw StateError(file.string() + " is not valid TOML: " + std::string(e.description()));
  }
  g = GridSpec{};
  g.cells = t["cells"].value_or(std::int64_t{0});
  auto list = [&](const char* key, auto push) {
    if (const toml::array* a = t[key].as_array())
      for (const auto& x : *a) push(x);
  };
  list("shape", [&](const toml::node& x) { g.shape.push_back(x.value_or(std::int64_t{0})); });
  list("names", [&](const toml::node& x) { g.names.push_back(x.value_or(std::string())); });
  list("lower", [&](const toml::node& x) { g.lower.push_back(x.value_or(0.0)); });
  list("upper", [&](const toml::node& x) { g.upper.push_back(x.value_or(0.0)); });
  if (t["kind"].value_or(std::string("grid")) != "cvt") return true;

  const std::string name = t["centroids"].value_or(std::string("centroids.csv"));
  if (name.empty() || name == "." || name == ".." || name.find('/') != std::string::npos)
    throw StateError(file.string() + " names the centroids file '" + name +
                     "', which is no file of the run directory (qdrun writes centroids.csv)");
  const fs::path csv_file = run_dir / name;
  if (!exists_nofollow(csv_file))
    throw StateError(csv_file.string() + " is missing (grid.toml names it: the run's CVT centroids)");
  const std::string csv = read_run_file(csv_file, kMaxCentroidsBytes);
  char crc[16];
  std::snprintf(crc, sizeof(crc), "%08x", crc32c(csv.data(), csv.size()));
  if (t["centroids_crc32c"].value_or(std::string()) != crc)
    throw StateError(csv_file.string() + " does not match the checksum grid.toml records for it (edited or damaged)");
  std::istringstream lines(csv);
  std::string line;
  std::getline(lines, line);  // header
  const std::size_t dims = g.dims();
  while (std::getline(lines, line)) {
    std::istringstream row(line);
    std::string field;
    std::getline(row, field, ',');  // centroid index
    for (std::size_t d = 0; d < dims && std::getline(row, field, ','); ++d) {
      try {
        g.centroids.push_back(std::stod(field));
      } catch (const std::exception&) {
        throw StateError(csv_file.string() + ": '" + field + "' is not a number");
      }
    }
  }
  if (dims == 0 || g.centroids.size() != static_cast<std::size_t>(g.cells) * dims)
    throw StateError(csv_file.string() + " holds " + std::to_string(g.centroids.size()) + " values for " +
                     std::to_string(g.cells) + " cells of " + std::to_string(dims) + " dimensions");
  return true;
}

void check_grid(const GridSpec& g, const std::string& who) {
  const std::size_t dims = g.dims();
  if (g.cells <= 0 || dims == 0 || g.shape.empty()) throw PluginError(who + " declares an empty grid");
  if (g.lower.size() != dims || g.upper.size() != dims)
    throw PluginError(who + " declares " + std::to_string(dims) + " dimensions with another number of bounds");
  if (g.is_cvt()) {
    if (g.shape.size() != 1 || g.shape[0] != g.cells)
      throw PluginError(who + " declares a CVT of " + std::to_string(g.cells) + " cells whose shape is not [cells]");
    if (g.centroids.size() != static_cast<std::size_t>(g.cells) * dims)
      throw PluginError(who + " declares " + std::to_string(g.cells) + " cells of " + std::to_string(dims) +
                        " dimensions but " + std::to_string(g.centroids.size()) + " centroid values");
    for (double v : g.centroids)
      if (!std::isfinite(v)) throw PluginError(who + " declares a non-finite centroid");
    if (!g.labels.empty()) throw PluginError(who + " declares bin labels for a CVT, whose cells are no bins");
    return;
  }
  if (g.shape.size() != dims)
    throw PluginError(who + " declares a grid of " + std::to_string(g.shape.size()) +
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

Components build_components(const Experiment& ex, const Registry& registry, const GridSpec* stored_grid) {
  Components c;
  BuildContext ctx;
  ctx.seed = ex.settings.seed;
  c.environment = create<Environment>(registry, ex.environment, ctx);
  const EnvironmentInfo info = c.environment->info();
  const std::string env_name = "environment '" + ex.environment.type + "'";
  if (info.parameters < 0) throw PluginError(env_name + " reports a negative parameter count");
  if (info.parameters > 0) {
    c.shape = PolicyShape::direct(static_cast<std::size_t>(info.parameters));
  } else {
    if (info.observation_size <= 0 || info.action_size <= 0)
      throw PluginError(env_name + " reports no observation or action size");
    c.shape = PolicyShape(info.observation_size, ex.settings.hidden, info.action_size);
  }
  if (info.persistent_worlds < 0 || info.persistent_worlds > kMaxPersistentWorlds)
    throw PluginError(env_name + " reports " + std::to_string(info.persistent_worlds) + " persistent worlds (0 to " +
                      std::to_string(kMaxPersistentWorlds) + " allowed)");
  ctx.policy = &c.shape;

  // The task's fitness, for the QD metrics and fitness insertion.
  c.has_fitness = info.has_fitness;
  c.fitness_lower_bound =
      std::isnan(ex.settings.fitness_lower_bound) ? info.fitness_lower_bound : ex.settings.fitness_lower_bound;
  if (!c.has_fitness && !std::isnan(ex.settings.fitness_lower_bound))
    throw InputError("[experiment] fitness_lower_bound is set, but " + env_name +
                     " declares no fitness (its README says what its traces report)");
  if (!c.has_fitness && ex.settings.insertion == InsertionRule::kFitness)
    throw InputError("[experiment] insertion = \"fitness\" needs a task fitness, but " + env_name +
                     " declares none; use insertion = \"coin-flip\"");
  if (c.has_fitness && std::isinf(c.fitness_lower_bound))
    throw PluginError(env_name + " declares an infinite fitness lower bound");

  if (ex.descriptor.entry->info->flags & kWrapsDescriptor) {
    // A descriptor adapter: the descriptor it wraps first (resolve() chose it, by default the
    // environment's own).
    c.wrapped = create<Descriptor>(registry, ex.wrapped, ctx);
    check_grid(c.wrapped->grid(), "descriptor '" + ex.wrapped.type + "' (" + ex.wrapped.entry->plugin->path + ")");
    ctx.wrapped = c.wrapped.get();
  }
  ctx.stored_grid = stored_grid;
  c.descriptor = create<Descriptor>(registry, ex.descriptor, ctx);
  ctx.wrapped = nullptr;
  ctx.stored_grid = nullptr;
  c.grid = c.descriptor->grid();
  check_grid(c.grid, "descriptor '" + ex.descriptor.type + "' (" + ex.descriptor.entry->plugin->path + ")");

  c.representation = create<Representation>(registry, ex.representation, ctx);
  const int latent = c.representation->latent_size();
  if (latent < 0 || static_cast<std::size_t>(latent) > c.shape.param_count())
    throw ConfigError("latent", ex.representation.config.where("latent") + ": [representation] latent size " +
                                    std::to_string(latent) + " is larger than the policy's parameter count " +
                                    std::to_string(c.shape.param_count()));
  ctx.latent_size = latent;
  ctx.batch = ex.settings.batch;
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

  for (const ComponentConfig* cc :
       {&ex.environment, &ex.wrapped, &ex.descriptor, &ex.representation, &ex.mutator, &ex.initial}) {
    if (!cc->entry) continue;  // no descriptor adapter: nothing wrapped
    const PluginInfo& pi = *cc->entry->plugin->info;
    c.provenance.push_back("{ table = " + toml_string(cc->table) + ", component = " + toml_string(cc->type) +
                           ", plugin = " + toml_string(pi.plugin_name) + ", version = " +
                           toml_string(pi.plugin_version) + ", path = " + toml_string(cc->entry->plugin->path) + " }");
  }
  return c;
}

}  // namespace qd::runtime
