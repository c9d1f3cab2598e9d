// qdrun --list and --describe (describe.hpp).
#include "describe.hpp"

#include "runtime/config_schema.hpp"

#include <qd/errors.hpp>

#include <cmath>
#include <cstdio>
#include <sstream>

namespace qd::app {
using runtime::ComponentEntry;
using runtime::core_tables;
using runtime::kComponentTables;
using runtime::range_text;
using runtime::Registry;

std::string describe_params(const ParamSpec* params, std::size_t count) {
  std::ostringstream o;
  if (count == 0) o << "  (no parameters)\n";
  for (std::size_t i = 0; i < count; ++i) {
    const ParamSpec& s = params[i];
    o << "  " << s.key << " (" << to_string(s.type) << ", default " << s.default_value;
    if (s.type == ParamType::kInteger || s.type == ParamType::kFloat || s.type == ParamType::kIntegerList ||
        s.type == ParamType::kFloatList) {
      if (!std::isinf(s.min) || !std::isinf(s.max)) o << ", range " << range_text(s);
    }
    if (s.choices) o << ", one of " << s.choices;
    o << ")\n      " << (s.help ? s.help : "") << "\n";
  }
  return o.str();
}

std::string describe_table(const std::string& name, const Registry& registry) {
  if (name == "plugins")
    return "[plugins] (core): where plugin libraries are searched, before qdrun's own <prefix>/lib/qd/plugins\n"
           "  path (list of strings, default [])\n"
           "      plugin directories, searched after --plugin-path and QD_PLUGIN_PATH; relative to the experiment "
           "file\n"
           "  search_path (list of strings, written by qdrun)\n"
           "      the user directories a run searched (--plugin-path, QD_PLUGIN_PATH, path), absolute; a run's "
           "config.toml records it, and --resume, --replay and --latents search it after the current ones\n";
  for (const auto& ct : kComponentTables) {
    if (name != ct.name) continue;
    std::string purpose = "the " + std::string(to_string(ct.kind)) + " component";
    if (name == "mutator") purpose = "the variation operator of loops n >= 1 (a mutator component)";
    if (name == "initial") purpose = "the loop-0 sampler (a mutator component that needs no parents)";
    if (name == "representation") purpose = "the latent model of the policy parameters (a representation component)";
    if (name == "descriptor")
      purpose =
          "the behaviour descriptor (a descriptor component); a descriptor adapter such as \"cvt\" wraps the "
          "descriptor of its sub-table [descriptor.wraps] (type and keys; default: the environment's own)";
    if (name == "environment") purpose = "the task (an environment component)";
    std::string dflt = ct.default_type == nullptr ? "required"
                       : *ct.default_type         ? "default \"" + std::string(ct.default_type) + "\""
                                                  : "default: the environment's own descriptor";
    std::string known;
    for (const auto& c : registry.components())
      if (c.info->kind == ct.kind) known += (known.empty() ? "" : ", ") + std::string(c.info->name);
    return "[" + name + "] (core): " + purpose + "\n  type (string, " + dflt +
           ")\n      the component's name; the table's other keys are that component's parameters (qdrun "
           "--describe <type>). An include or --set that changes type drops the keys the new component does not "
           "declare\n      available: " +
           (known.empty() ? std::string("(none found)") : known) + "\n";
  }
  return "";
}

void list_components(const Registry& reg) {
  for (Kind kind : {Kind::kEnvironment, Kind::kDescriptor, Kind::kRepresentation, Kind::kMutator}) {
    std::printf("%ss:\n", to_string(kind));
    for (const auto& c : reg.components()) {
      if (c.info->kind != kind) continue;
      std::printf("  %-20s %s\n  %-20s   (plugin %s %s, %s)\n", c.info->name, c.info->summary ? c.info->summary : "",
                  "", c.plugin->info->plugin_name, c.plugin->info->plugin_version, c.plugin->path.c_str());
    }
  }
  if (!reg.rejected().empty()) {
    std::printf("rejected libraries:\n");
    for (const auto& r : reg.rejected()) std::printf("  %s\n", r.reason.c_str());
  }
  std::printf("plugin search path:\n");
  for (const auto& d : reg.search_dirs()) std::printf("  %s\n", d.c_str());
}

void describe(const Registry& reg, const std::string& name) {
  for (const auto& t : core_tables()) {
    if (name == t.name) {
      std::printf("[%s] (core)\n%s", t.name, describe_params(t.params, t.count).c_str());
      return;
    }
  }
  if (const std::string text = describe_table(name, reg); !text.empty()) {
    std::printf("%s", text.c_str());
    return;
  }
  const ComponentEntry* e = reg.find(name);
  if (!e) {
    std::string known;
    for (const auto& t : core_tables()) known += std::string(known.empty() ? "" : ", ") + t.name;
    for (const char* t : {"plugins", "environment", "descriptor", "representation", "mutator", "initial"})
      known += ", " + std::string(t);
    for (const auto& c : reg.components()) known += ", " + std::string(c.info->name);
    throw InputError("--describe: unknown component or table '" + name + "'; known: " + known);
  }
  std::printf("%s '%s': %s\n  plugin %s %s (%s)\nparameters (besides type = \"%s\"):\n%s", to_string(e->info->kind),
              e->info->name, e->info->summary ? e->info->summary : "", e->plugin->info->plugin_name,
              e->plugin->info->plugin_version, e->plugin->path.c_str(), e->info->name,
              describe_params(e->info->params, e->info->param_count).c_str());
}

}  // namespace qd::app
