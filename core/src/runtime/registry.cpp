#include "runtime/registry.hpp"

#include "runtime/plugin_library.hpp"
#include "runtime/plugin_probe.hpp"

#include <qd/errors.hpp>

#include <boost/dll/runtime_symbol_info.hpp>

#include <algorithm>
#include <deque>

namespace qd::runtime {
namespace fs = std::filesystem;
namespace dll = boost::dll;

bool Rejection::could_provide(const std::string& name) const {
  if (!is_plugin) return false;
  return !names_known || std::find(names.begin(), names.end(), name) != names.end();
}

void Registry::add_search_dir(const fs::path& dir, DirOrigin origin) {
  if (dir.empty()) return;
  std::error_code ec;
  fs::path canon = fs::weakly_canonical(fs::absolute(dir, ec), ec);
  if (ec) canon = dir;
  if (std::find(dirs_.begin(), dirs_.end(), canon) != dirs_.end()) return;
  dirs_.push_back(canon);
  origins_.push_back(origin);
}

std::vector<std::string> Registry::user_dirs() const {
  std::vector<std::string> out;
  for (std::size_t i = 0; i < dirs_.size(); ++i)
    if (origins_[i] == DirOrigin::kUser) out.push_back(dirs_[i].string());
  return out;
}

void Registry::discover() {
  std::vector<fs::path> candidates;
  for (const auto& dir : dirs_) {
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) continue;
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(dir, ec)) {
      if (!looks_like_plugin_file(e.path())) continue;
      std::error_code ec2;
      if (e.is_regular_file(ec2)) {
        files.push_back(e.path());
        continue;
      }
      // Named like a plugin but no library (a dangling symlink left by a removed build, a
      // directory, a FIFO): left out, and --list says why.
      Rejection r;
      r.path = e.path().string();
      r.reason = r.path + ": " + not_a_library(e.path(), ec2);
      if (std::none_of(rejected_.begin(), rejected_.end(), [&](const Rejection& x) { return x.path == r.path; }))
        rejected_.push_back(std::move(r));
    }
    std::sort(files.begin(), files.end());
    for (const auto& f : files) {
      const auto same = [&](const fs::path& p) {
        std::error_code ec2;
        return fs::equivalent(p, f, ec2);
      };
      if (std::any_of(plugins_.begin(), plugins_.end(), [&](const auto& p) { return same(p->path); }) ||
          std::any_of(candidates.begin(), candidates.end(), same))
        continue;
      candidates.push_back(f);
    }
  }
  // Every library is probed in a process of its own, a few at once (fewer when a process limit
  // refuses more); then they are registered in search order (the first library that provides a
  // name wins).
  constexpr std::size_t kParallelProbes = 4;
  std::vector<Rejection> seen(candidates.size());
  std::vector<Probe> probes(candidates.size());
  std::vector<std::string> errors(candidates.size());
  std::deque<std::size_t> running;
  for (std::size_t next = 0; next < candidates.size() || !running.empty();) {
    while (next < candidates.size() && running.size() < kParallelProbes) {
      try {
        check_file(candidates[next], seen[next]);
      } catch (const PluginError& e) {
        errors[next++] = e.what();
        continue;
      }
      try {
        probes[next] = start_probe(candidates[next]);
      } catch (const SystemError&) {
        if (running.empty()) throw;  // not even one process: the system's failure (exit 4)
        break;                       // again once a running probe has ended
      }
      running.push_back(next++);
    }
    if (running.empty()) continue;
    finish_probe(probes[running.front()]);
    running.pop_front();
  }
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    // A probe the system refused descriptors or memory may have competed with the others (each
    // holds a pipe): alone, now, it is asked once more before that is the verdict.
    if (errors[i].empty() && !probes[i].message.empty() && probes[i].message[0] == 'S') {
      probes[i] = start_probe(candidates[i]);
      finish_probe(probes[i]);
    }
    try {
      if (!errors[i].empty()) throw PluginError(errors[i]);
      std::shared_ptr<ProbeCopy> copy = verdict(probes[i], seen[i]);
      const PluginInfo* info = &copy->info;
      add(candidates[i], info, nullptr, std::move(copy));
    } catch (const PluginError& e) {
      seen[i].path = candidates[i].string();
      seen[i].reason = e.what();
      rejected_.push_back(std::move(seen[i]));
    }
  }
}

std::shared_ptr<LoadedPlugin> Registry::load(const fs::path& path) {
  Rejection seen;
  return load(path, seen);
}

std::shared_ptr<LoadedPlugin> Registry::load(const fs::path& path, Rejection& seen) {
  check_file(path, seen);
  Opened opened = open_checked(path, seen);
  pin(path);
  auto loaded = add(path, opened.info, opened.library, nullptr);
  loaded->own_info = opened.info;
  return loaded;
}

std::shared_ptr<LoadedPlugin> Registry::add(const fs::path& path, const PluginInfo* info,
                                            std::shared_ptr<const void> library,
                                            std::shared_ptr<const void> probe_copy) {
  std::error_code ec;
  auto loaded = std::make_shared<LoadedPlugin>();
  loaded->library = std::move(library);
  loaded->path = fs::weakly_canonical(path, ec).string();
  loaded->info = info;
  loaded->probe_copy = std::move(probe_copy);
  plugins_.push_back(loaded);
  // A name an earlier library already provides is shadowed: only that component is left out,
  // never the library's others.
  for (std::uint32_t i = 0; i < info->component_count; ++i) {
    const ComponentInfo& c = info->components[i];
    if (const ComponentEntry* prior = find(c.name)) {
      shadowed_.push_back({c.name, c.kind, loaded->path, prior->plugin->path});
      continue;
    }
    components_.push_back({&c, loaded});
  }
  return loaded;
}

std::vector<std::string> Registry::warnings() const {
  std::vector<std::string> out;
  std::vector<std::pair<std::string, std::string>> pairs;
  for (const auto& s : shadowed_)
    if (std::find(pairs.begin(), pairs.end(), std::pair{s.path, s.winner}) == pairs.end())
      pairs.emplace_back(s.path, s.winner);
  for (const auto& [path, winner] : pairs) {
    std::string names;
    for (const auto& s : shadowed_)
      if (s.path == path && s.winner == winner) names += (names.empty() ? "'" : ", '") + s.name + "'";
    out.push_back(path + ": " + names + " left out, already provided by " + winner +
                  " (first in the plugin search path wins; the library's other components stay available)");
  }
  return out;
}

const ComponentEntry* Registry::find(const std::string& name) const {
  for (const auto& c : components_)
    if (name == c.info->name) return &c;
  return nullptr;
}

const ComponentEntry& Registry::require(const std::string& name, Kind kind) const {
  const ComponentEntry* e = find(name);
  if (e && e->info->kind == kind) return *e;
  std::string msg;
  if (e) {
    msg =
        "'" + name + "' is a " + to_string(e->info->kind) + " (from " + e->plugin->path + "), not a " + to_string(kind);
    for (const auto& s : shadowed_)
      if (s.name == name && s.kind == kind)
        msg += "; the " + std::string(to_string(kind)) + " '" + name + "' of " + s.path + " is shadowed by it";
  } else {
    msg = "unknown " + std::string(to_string(kind)) + " '" + name + "'";
  }
  std::string known;
  for (const auto& c : components_)
    if (c.info->kind == kind) known += (known.empty() ? "" : ", ") + std::string(c.info->name);
  msg += "; known " + std::string(to_string(kind)) + "s: " + (known.empty() ? "(none)" : known);
  std::string dirs;
  for (const auto& d : dirs_) dirs += (dirs.empty() ? "" : ":") + d.string();
  msg += "; plugin search path: " + (dirs.empty() ? "(empty)" : dirs);
  // Only the libraries that might have provided the name: any other rejection is noise here
  // (qdrun --list shows them all).
  std::size_t others = 0;
  std::string candidates;
  for (const auto& r : rejected_) {
    if (r.could_provide(name))
      candidates += "\n  rejected " + r.reason;
    else
      ++others;
  }
  if (others > 0 && !e)
    msg += " (" + std::to_string(others) + " other rejected librar" + (others == 1 ? "y" : "ies") +
           " could not have provided it; qdrun --list shows why)";
  throw InputError(msg + candidates);
}

Component* Registry::construct(const ComponentEntry& entry, const Config& config, const BuildContext& ctx) const {
  LoadedPlugin& plugin = *entry.plugin;
  if (!plugin.library) {
    // Probed only: loaded now, into this process, and held to what the probe read.
    Rejection seen;
    Opened opened = open_checked(plugin.path, seen);
    const PluginInfo& now = *opened.info;
    bool same = now.component_count == plugin.info->component_count &&
                std::strcmp(now.plugin_name, plugin.info->plugin_name) == 0;
    for (std::uint32_t i = 0; same && i < now.component_count; ++i)
      same = now.components[i].kind == plugin.info->components[i].kind &&
             now.components[i].flags == plugin.info->components[i].flags &&
             std::strcmp(now.components[i].name, plugin.info->components[i].name) == 0;
    if (!same)
      throw PluginError(plugin.path + ": changed on disk since qdrun started (it declares other components now)");
    pin(plugin.path);
    plugin.own_info = opened.info;
    plugin.library = opened.library;
  }
  const ComponentInfo* own = nullptr;
  for (std::uint32_t i = 0; i < plugin.own_info->component_count; ++i)
    if (std::strcmp(plugin.own_info->components[i].name, entry.info->name) == 0) own = &plugin.own_info->components[i];
  if (!own) throw PluginError(plugin.path + ": no longer declares component '" + entry.info->name + "'");
  try {
    Component* c = own->create(config, ctx);
    if (!c)
      throw PluginError("component '" + std::string(entry.info->name) + "' from " + entry.plugin->path +
                        ": factory returned nothing");
    return c;
  } catch (const ConfigError&) {
    throw;  // the caller adds the key's location
  } catch (const PluginError&) {
    throw;
  } catch (const std::exception& e) {
    // Copy the text: the exception object lives in plugin memory.
    throw PluginError("component '" + std::string(entry.info->name) + "' from " + entry.plugin->path +
                      " failed to construct: " + e.what());
  } catch (...) {
    throw PluginError("component '" + std::string(entry.info->name) + "' from " + entry.plugin->path +
                      " failed to construct (unknown exception)");
  }
}

void Registry::destroy(Component* c, const ComponentEntry&) noexcept {
  delete c;
}

void Registry::throw_wrong_type(const ComponentEntry& entry) {
  throw PluginError("component '" + std::string(entry.info->name) + "' from " + entry.plugin->path +
                    " is registered as a " + to_string(entry.info->kind) + " but its object is not one");
}

fs::path installed_plugin_dir() {
  std::error_code ec;
  const fs::path exe = dll::program_location(ec);
  if (ec) return {};
  return exe.parent_path().parent_path() / "lib" / "qd" / "plugins";
}

fs::path build_tree_plugin_dir() {
#if defined(QD_BUILD_PLUGIN_DIR) && defined(QD_BUILD_BIN_DIR)
  // Decided at run time, by where the executable is: the same binary installed elsewhere (even into
  // a prefix inside the build tree, as tests/install does) must not see this tree's plugins.
  std::error_code ec;
  const fs::path exe = dll::program_location(ec);
  if (ec || !fs::equivalent(exe.parent_path(), fs::path(QD_BUILD_BIN_DIR), ec) || ec) return {};
  return fs::path(QD_BUILD_PLUGIN_DIR);
#else
  return {};
#endif
}

}  // namespace qd::runtime
