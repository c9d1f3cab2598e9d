#include "runtime/registry.hpp"

#include <qd/errors.hpp>
#include <qd/version.hpp>

#include <vector>  // boost/dll/library_info.hpp needs it first with BOOST_DLL_USE_STD_FS (Boost 1.74)

#include <boost/dll/library_info.hpp>
#include <boost/dll/runtime_symbol_info.hpp>
#include <boost/dll/shared_library.hpp>

#include <dlfcn.h>
#include <algorithm>
#include <cstring>
#include <set>

namespace qd::runtime {
namespace fs = std::filesystem;
namespace dll = boost::dll;

namespace {
constexpr const char* kEntrySymbol = "qd_plugin_entry_v1";

bool looks_like_plugin_file(const fs::path& p) {
  const std::string name = p.filename().string();
  return name.rfind("qd_", 0) == 0 && p.extension() == ".so";
}
}  // namespace

void Registry::add_search_dir(const fs::path& dir) {
  if (dir.empty()) return;
  std::error_code ec;
  fs::path canon = fs::weakly_canonical(dir, ec);
  if (ec) canon = dir;
  if (std::find(dirs_.begin(), dirs_.end(), canon) == dirs_.end()) dirs_.push_back(canon);
}

void Registry::discover() {
  for (const auto& dir : dirs_) {
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) continue;
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(dir, ec))
      if (e.is_regular_file(ec) && looks_like_plugin_file(e.path())) files.push_back(e.path());
    std::sort(files.begin(), files.end());
    for (const auto& f : files) {
      const bool already = std::any_of(plugins_.begin(), plugins_.end(), [&](const auto& p) {
        std::error_code ec2;
        return fs::equivalent(p->path, f, ec2);
      });
      if (already) continue;
      try {
        load(f);
      } catch (const PluginError& e) {
        rejected_.push_back({f.string(), e.what()});
      }
    }
  }
}

std::shared_ptr<LoadedPlugin> Registry::load(const fs::path& path) {
  const std::string where = path.string();
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw PluginError(where + ": no such plugin file");

  // 1. The entry alias must be present. Reading the ELF symbol table first means a shared library
  //    that is not a plugin is never dlopen'ed (so its static initialisers never run).
  try {
    dll::library_info info(path, /*throw_if_not_native=*/true);
    const auto symbols = info.symbols();
    if (std::find(symbols.begin(), symbols.end(), kEntrySymbol) == symbols.end())
      throw PluginError(where + ": not a qd plugin (no exported symbol '" + kEntrySymbol +
                        "'; was it built with QD_PLUGIN and qd_add_plugin?)");
  } catch (const PluginError&) {
    throw;
  } catch (const std::exception& e) {
    throw PluginError(where + ": not a loadable shared library (" + e.what() + ")");
  }

  auto lib = std::make_shared<dll::shared_library>();
  try {
    lib->load(path, dll::load_mode::rtld_now | dll::load_mode::rtld_local);
  } catch (const std::exception& e) {
    throw PluginError(where + ": dlopen failed: " + e.what());
  }
  PluginEntryFn entry = nullptr;
  try {
    entry = lib->get_alias<const PluginInfo*()>(kEntrySymbol);
  } catch (const std::exception& e) {
    throw PluginError(where + ": cannot resolve '" + kEntrySymbol + "': " + e.what());
  }
  const PluginInfo* info = nullptr;
  try {
    info = entry();
  } catch (...) {
    throw PluginError(where + ": the plugin entry function threw");
  }
  if (!info) throw PluginError(where + ": the plugin entry returned no information");

  // 2-4. ABI version (read first, nothing else is trusted before it), struct size, fingerprint.
  if (info->abi_version != kPluginAbiVersion)
    throw PluginError(where + ": plugin ABI version " + std::to_string(info->abi_version) +
                      ", but this qdrun expects " + std::to_string(kPluginAbiVersion) +
                      "; rebuild the plugin against this qd installation");
  if (info->info_size != sizeof(PluginInfo))
    throw PluginError(where + ": plugin info size " + std::to_string(info->info_size) + " bytes, expected " +
                      std::to_string(sizeof(PluginInfo)) + "; the plugin was built against other qd headers");
  const char* fp = info->build_fingerprint ? info->build_fingerprint : "";
  if (std::strcmp(fp, build_fingerprint()) != 0)
    throw PluginError(where + ": build fingerprint '" + fp + "' does not match the core's '" + build_fingerprint() +
                      "'; rebuild the plugin with the same compiler, Eigen and flags");
  // 5. File name.
  const std::string plugin_name = info->plugin_name ? info->plugin_name : "";
  if (plugin_name.empty() || path.filename().string() != "qd_" + plugin_name + ".so")
    throw PluginError(where + ": plugin calls itself '" + plugin_name + "', so its file must be named qd_" +
                      plugin_name + ".so");
  // 6. Components: well-formed, unique inside the plugin and against everything loaded before.
  if (info->component_count == 0 || !info->components) throw PluginError(where + ": plugin registers no component");
  std::set<std::string> own;
  for (std::uint32_t i = 0; i < info->component_count; ++i) {
    const ComponentInfo& c = info->components[i];
    if (!c.name || !*c.name || !c.create)
      throw PluginError(where + ": component " + std::to_string(i) + " is malformed");
    if (c.kind < Kind::kEnvironment || c.kind > Kind::kMutator)
      throw PluginError(where + ": component '" + c.name + "' has an unknown kind");
    if (!own.insert(c.name).second)
      throw PluginError(where + ": component name '" + std::string(c.name) + "' is registered twice by this plugin");
    if (const ComponentEntry* prior = find(c.name))
      throw PluginError(where + ": component name '" + std::string(c.name) + "' is already provided by " +
                        prior->plugin->path + " (first in the plugin search path wins)");
  }

  // An accepted plugin is never unloaded, not even at exit: its dependencies (libgomp for the
  // autoencoder) keep their static state, and no destructor of a plugin-made object can outlive its
  // code. Promoting the loaded library to RTLD_NODELETE does that; the extra handle is never closed.
  if (!::dlopen(path.c_str(), RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE))
    throw PluginError(where + ": cannot pin the loaded plugin: " + ::dlerror());
  auto loaded = std::make_shared<LoadedPlugin>();
  loaded->library = lib;
  loaded->path = fs::weakly_canonical(path, ec).string();
  loaded->info = info;
  plugins_.push_back(loaded);
  for (std::uint32_t i = 0; i < info->component_count; ++i) components_.push_back({&info->components[i], loaded});
  return loaded;
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
  } else {
    msg = "unknown " + std::string(to_string(kind)) + " '" + name + "'";
  }
  std::string known;
  for (const auto& c : components_)
    if (c.info->kind == kind) known += (known.empty() ? "" : ", ") + std::string(c.info->name);
  msg += "; known " + std::string(to_string(kind)) + "s: " + (known.empty() ? "(none)" : known);
  if (!rejected_.empty()) {
    msg += "; rejected plugin libraries:";
    for (const auto& r : rejected_) msg += " [" + r.reason + "]";
  }
  std::string dirs;
  for (const auto& d : dirs_) dirs += (dirs.empty() ? "" : ":") + d.string();
  msg += "; plugin search path: " + (dirs.empty() ? "(empty)" : dirs);
  throw InputError(msg);
}

Component* Registry::construct(const ComponentEntry& entry, const Config& config, const BuildContext& ctx) const {
  try {
    Component* c = entry.info->create(config, ctx);
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

fs::path build_tree_plugin_dir() {
#ifdef QD_BUILD_PLUGIN_DIR
  return fs::path(QD_BUILD_PLUGIN_DIR);
#else
  return {};
#endif
}

fs::path installed_plugin_dir() {
  std::error_code ec;
  const fs::path exe = dll::program_location(ec);
  if (ec) return {};
  return exe.parent_path().parent_path() / "lib" / "qd" / "plugins";
}

}  // namespace qd::runtime
