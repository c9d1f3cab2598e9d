// Configuration, stage 3: resolution (experiment.hpp). The document's tables against the schema
// and the registry's components: each component table's type found, its keys checked against what
// the component declares, and the resolved configuration written as TOML.
#include "runtime/experiment.hpp"

#include "runtime/config_toml.hpp"
#include "runtime/cost_model.hpp"

#include <qd/errors.hpp>

#include <algorithm>

namespace qd::runtime {

namespace {

// Fills `cc` with the defaults of `entry` and appends its resolved table to `ex.resolved_toml`.
void resolve_default_component(Experiment& ex, ComponentConfig& cc, const ComponentEntry& entry) {
  cc.type = entry.info->name;
  cc.entry = &entry;
  cc.implied = true;
  cc.config = validate_table(nullptr, cc.table, entry.info->params, entry.info->param_count, cc.type);
  toml::table out;
  out.insert_or_assign("type", cc.type);
  put_config(out, cc.config, entry.info->params, entry.info->param_count);
  // A dotted table name ("descriptor.wraps") nests: [descriptor.wraps] after [descriptor].
  const std::size_t dot = cc.table.find('.');
  toml::table wrapper;
  if (dot == std::string::npos) {
    wrapper.insert_or_assign(cc.table, std::move(out));
  } else {
    toml::table parent;
    parent.insert_or_assign(cc.table.substr(dot + 1), std::move(out));
    wrapper.insert_or_assign(cc.table.substr(0, dot), std::move(parent));
  }
  ex.resolved_toml += "\n" + toml_text(wrapper);
}

// [descriptor] (or an adapter's [descriptor.wraps]) without a type: the environment's default
// descriptor, as its component info declares it (no plugin object needed). Appended after the
// other tables, where a run's config.toml has always had it.
void resolve_default_descriptors(Experiment& ex, const Registry& registry) {
  const char* dflt = ex.environment.entry->info->default_descriptor;
  const std::string env_name = "environment '" + ex.environment.type + "'";
  if (!ex.descriptor.entry) {
    if (!dflt) throw InputError(env_name + " has no default descriptor; add [descriptor] type = ...");
    resolve_default_component(ex, ex.descriptor, registry.require(dflt, Kind::kDescriptor));
    if (ex.descriptor.entry->info->flags & kWrapsDescriptor) ex.wrapped.table = "descriptor.wraps";
  }
  if (!(ex.descriptor.entry->info->flags & kWrapsDescriptor) || ex.wrapped.entry) return;
  if (!dflt)
    throw InputError(env_name + " has no default descriptor for " + ex.descriptor.type + " to wrap; add [" +
                     ex.wrapped.table + "] type = ...");
  const ComponentEntry& entry = registry.require(dflt, Kind::kDescriptor);
  if (entry.info->flags & kWrapsDescriptor)
    throw InputError(env_name + "'s default descriptor '" + dflt +
                     "' wraps a descriptor itself; name the one to wrap in [" + ex.wrapped.table + "]");
  resolve_default_component(ex, ex.wrapped, entry);
}

}  // namespace

Experiment resolve(const Document& doc, const Registry& registry) {
  const toml::table& root = doc.impl->root;
  std::vector<std::string> allowed = {"experiment", "policy", "output", "evaluation", "cost", "plugins"};
  for (const auto& t : kComponentTables) allowed.emplace_back(t.name);
  for (const auto& [k, v] : root) {
    const std::string key(k.str());
    if (std::find(allowed.begin(), allowed.end(), key) == allowed.end())
      fail_at(v,
              "unknown table '" + key + "'" + suggestion(key, allowed) + "; experiment files have: " + join(allowed));
  }

  Experiment ex;
  ex.file = doc.impl->file;
  ex.plugin_paths = doc.plugin_paths();
  toml::table resolved;
  resolve_core_tables(root, ex.file, ex.settings, resolved);
  read_cost_model(doc);  // checked with every run; only --dry-run reads it
  // [cost] is left out: no result depends on it (cost_model.hpp).

  for (const auto& ct : kComponentTables) {
    ComponentConfig* cc = nullptr;
    const std::string table = ct.name;
    if (table == "environment") cc = &ex.environment;
    if (table == "descriptor") cc = &ex.descriptor;
    if (table == "representation") cc = &ex.representation;
    if (table == "mutator") cc = &ex.mutator;
    if (table == "initial") cc = &ex.initial;
    cc->table = table;
    const toml::table* t = sub_table(root, ct.name);
    const toml::node* type_node = t ? t->get("type") : nullptr;
    if (type_node && !type_node->is_string()) fail_at(*type_node, table + ".type must be a string (a component name)");
    if (type_node) {
      cc->type = type_node->as_string()->get();
    } else if (ct.default_type && *ct.default_type) {
      cc->type = ct.default_type;
    } else if (ct.default_type) {
      // Descriptor: the environment's default (resolve_default_descriptors, after the other tables).
      if (t && !t->empty()) fail_at(*t, "[descriptor] sets options but no type; add type = \"<descriptor name>\"");
      continue;
    } else {
      throw InputError((ex.file.empty() ? std::string("<experiment>") : ex.file.string()) + ": [" + table +
                       "] with a type is required (see qdrun --list for the available " + to_string(ct.kind) + "s)");
    }
    try {
      cc->entry = &registry.require(cc->type, ct.kind);
    } catch (const InputError& err) {
      throw InputError((type_node ? location(*type_node) : std::string("default")) + ": " + table +
                       ".type: " + err.what());
    }
    const ComponentInfo& info = *cc->entry->info;
    // Keys written for a component that an include or --set replaced: those the new component does
    // not declare are dropped, with a note, instead of failing as unknown keys.
    std::vector<std::string> skip = {"type"};
    if (t) {
      std::string dropped, replaced;
      const auto origins = doc.impl->origins.find(table);
      for (const auto& [k, v] : *t) {
        const std::string key(k.str());
        if (key == "type" || origins == doc.impl->origins.end()) continue;
        const auto origin = origins->second.find(key);
        if (origin == origins->second.end() || !origin->second.known || origin->second.type == cc->type) continue;
        bool declared = false;
        for (std::uint32_t i = 0; i < info.param_count; ++i) declared = declared || key == info.params[i].key;
        if (declared) continue;
        skip.push_back(key);
        dropped += (dropped.empty() ? "" : ", ") + key + " (" + location(v) + ")";
        const std::string old_type = "\"" + origin->second.type + "\"";
        if (replaced.find(old_type) == std::string::npos) replaced += (replaced.empty() ? "" : ", ") + old_type;
      }
      if (!dropped.empty())
        ex.notes.push_back("[" + table + "] type = \"" + cc->type + "\" (" +
                           (type_node ? location(*type_node) : std::string("default")) + ") replaces " + replaced +
                           ": dropped " + dropped + ", which " + cc->type + " does not declare");
    }
    const bool adapter = (info.flags & kWrapsDescriptor) != 0;
    if (adapter) skip.push_back("wraps");
    cc->config = validate_table(t, table, info.params, info.param_count,
                                "component '" + cc->type + "' (" + cc->entry->plugin->path + ")", skip);
    toml::table out;
    out.insert_or_assign("type", cc->type);
    put_config(out, cc->config, info.params, info.param_count);
    // A descriptor adapter's [descriptor.wraps]: the descriptor it wraps, a component table of its
    // own (the environment's default descriptor, filled in after the other tables, when absent).
    if (adapter) {
      ex.wrapped.table = table + ".wraps";
      const toml::node* wraps = t ? t->get("wraps") : nullptr;
      if (wraps && !wraps->is_table())
        fail_at(*wraps, table + ".wraps must be a table ([" + table + ".wraps] with a type)");
      const toml::table* wt = wraps ? wraps->as_table() : nullptr;
      const toml::node* wtype = wt ? wt->get("type") : nullptr;
      if (wt && (!wtype || !wtype->is_string()))
        fail_at(*wraps, "[" + ex.wrapped.table + "] needs type = \"<descriptor name>\" (the descriptor that " +
                            cc->type + " wraps), or leave it out for the environment's own");
      if (wtype) {
        ex.wrapped.type = wtype->as_string()->get();
        try {
          ex.wrapped.entry = &registry.require(ex.wrapped.type, Kind::kDescriptor);
        } catch (const InputError& err) {
          throw InputError(location(*wtype) + ": " + ex.wrapped.table + ".type: " + err.what());
        }
        const ComponentInfo& winfo = *ex.wrapped.entry->info;
        if (winfo.flags & kWrapsDescriptor)
          fail_at(*wtype, "[" + ex.wrapped.table + "] type = \"" + ex.wrapped.type +
                              "\" wraps a descriptor itself; adapters do not nest");
        ex.wrapped.config =
            validate_table(wt, ex.wrapped.table, winfo.params, winfo.param_count,
                           "component '" + ex.wrapped.type + "' (" + ex.wrapped.entry->plugin->path + ")", {"type"});
        toml::table wout;
        wout.insert_or_assign("type", ex.wrapped.type);
        put_config(wout, ex.wrapped.config, winfo.params, winfo.param_count);
        out.insert_or_assign("wraps", std::move(wout));
      }
    }
    resolved.insert_or_assign(table, std::move(out));
  }
  // The user's plugin directories this run searches, recorded so that --resume, --replay and
  // --latents find the same plugins without the command line or environment that named them.
  const std::vector<std::string> search_path = registry.user_dirs();
  if (!ex.plugin_paths.empty() || !search_path.empty()) {
    toml::table t;
    auto put = [&t](const char* key, const std::vector<std::string>& list) {
      if (list.empty()) return;
      toml::array a;
      for (const auto& x : list) a.push_back(x);
      t.insert_or_assign(key, std::move(a));
    };
    put("path", ex.plugin_paths);
    put("search_path", search_path);
    resolved.insert_or_assign("plugins", std::move(t));
  }
  ex.resolved_toml = toml_text(resolved);
  resolve_default_descriptors(ex, registry);
  return ex;
}

}  // namespace qd::runtime
