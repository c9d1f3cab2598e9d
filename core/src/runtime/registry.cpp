#include "runtime/registry.hpp"

#include <qd/errors.hpp>
#include <qd/version.hpp>

#include <vector>  // boost/dll/library_info.hpp needs it first with BOOST_DLL_USE_STD_FS (Boost 1.74)

#include <boost/dll/library_info.hpp>
#include <boost/dll/runtime_symbol_info.hpp>
#include <boost/dll/shared_library.hpp>

#include <cxxabi.h>
#include <dlfcn.h>
#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <set>
#include <sstream>

namespace qd::runtime {
namespace fs = std::filesystem;
namespace dll = boost::dll;

namespace {
constexpr const char* kEntrySymbol = "qd_plugin_entry_v1";

bool looks_like_plugin_file(const fs::path& p) {
  const std::string name = p.filename().string();
  return name.rfind("qd_", 0) == 0 && p.extension() == ".so";
}

// What is wrong with a file that should be an ELF shared library, judged from its first bytes; empty
// when it looks like one. Checked here because Boost's ELF reader reports a text file as
// "basic_ios::clear: iostream error".
std::string not_elf_reason(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return "cannot be opened for reading";
  unsigned char id[5] = {0, 0, 0, 0, 0};
  in.read(reinterpret_cast<char*>(id), sizeof(id));
  const std::streamsize got = in.gcount();
  if (got == 0) return "is an empty file, not a shared library";
  if (got < 4 || id[0] != 0x7f || id[1] != 'E' || id[2] != 'L' || id[3] != 'F')
    return "is not a shared library (no ELF header: a text file or other junk named like a plugin)";
  if (got < 5 || id[4] != (sizeof(void*) == 8 ? 2 : 1))  // EI_CLASS: ELFCLASS64 = 2, ELFCLASS32 = 1
    return "is an ELF file for another word size than this qdrun's";
  return "";
}

// dlerror() text without the path it repeats, with a C++ symbol demangled.
std::string dlopen_reason(const std::string& path, std::string text) {
  if (text.rfind(path + ": ", 0) == 0) text.erase(0, path.size() + 2);
  const std::string tag = "undefined symbol: ";
  const auto at = text.find(tag);
  if (at == std::string::npos) return text;
  const std::string symbol = text.substr(at + tag.size());
  int status = 0;
  char* plain = abi::__cxa_demangle(symbol.c_str(), nullptr, nullptr, &status);
  std::string name = status == 0 && plain ? std::string(plain) + " (" + symbol + ")" : symbol;
  std::free(plain);
  return "undefined symbol " + name +
         ": the library needs code that neither it nor the libraries it links define (built against "
         "another qd, or a library missing from qd_add_plugin's LIBRARIES?)";
}

// The ';'-separated parts of two fingerprints that differ, for the mismatch message.
std::string fingerprint_difference(const std::string& plugin, const std::string& core) {
  auto parts = [](const std::string& s) {
    std::vector<std::string> out;
    std::stringstream in(s);
    for (std::string p; std::getline(in, p, ';');) out.push_back(p);
    return out;
  };
  const auto a = parts(plugin), b = parts(core);
  std::string only_plugin, only_core;
  for (const auto& p : a)
    if (std::find(b.begin(), b.end(), p) == b.end()) only_plugin += (only_plugin.empty() ? "" : ", ") + p;
  for (const auto& p : b)
    if (std::find(a.begin(), a.end(), p) == a.end()) only_core += (only_core.empty() ? "" : ", ") + p;
  return "plugin only: " + (only_plugin.empty() ? std::string("-") : only_plugin) +
         "; core only: " + (only_core.empty() ? std::string("-") : only_core);
}
}  // namespace

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
      Rejection seen;
      try {
        load(f, seen);
      } catch (const PluginError& e) {
        seen.path = f.string();
        seen.reason = e.what();
        rejected_.push_back(std::move(seen));
      }
    }
  }
}

std::shared_ptr<LoadedPlugin> Registry::load(const fs::path& path) {
  Rejection seen;
  return load(path, seen);
}

std::shared_ptr<LoadedPlugin> Registry::load(const fs::path& path, Rejection& seen) {
  const std::string where = path.string();
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw PluginError(where + ": no such plugin file");
  if (const std::string junk = not_elf_reason(path); !junk.empty()) throw PluginError(where + ": " + junk);

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
  } catch (const std::exception&) {
    // Boost's reader has nothing better to say than "iostream error" about a damaged file.
    throw PluginError(where +
                      ": not a loadable shared library (its ELF symbol table cannot be read: a truncated "
                      "or damaged file?)");
  }
  seen.is_plugin = true;

  auto lib = std::make_shared<dll::shared_library>();
  try {
    lib->load(path, dll::load_mode::rtld_now | dll::load_mode::rtld_local);
  } catch (const std::exception& e) {
    // Boost reports every dlopen failure as "Bad file descriptor"; dlopen's own message names the
    // cause (an undefined symbol, a dependency not found). The failure repeats, so ask again.
    std::string reason = e.what();
    if (void* h = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL)) {
      ::dlclose(h);
    } else if (const char* text = ::dlerror()) {
      reason = dlopen_reason(where, text);
    }
    throw PluginError(where + ": cannot be loaded: " + reason);
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
  // From here the structs have this qdrun's layout: their plain C strings can be read even when the
  // fingerprint differs, so a rejection can say which names the library would have provided.
  if (info->components)
    for (std::uint32_t i = 0; i < info->component_count; ++i)
      if (info->components[i].name) seen.names.emplace_back(info->components[i].name);
  seen.names_known = true;
  const char* fp = info->build_fingerprint ? info->build_fingerprint : "";
  if (std::strcmp(fp, build_fingerprint()) != 0)
    throw PluginError(where + ": build fingerprint '" + fp + "' does not match the core's '" + build_fingerprint() +
                      "' (" + fingerprint_difference(fp, build_fingerprint()) +
                      "); rebuild the plugin with the same compiler, Eigen and flags");
  // 5. File name.
  const std::string plugin_name = info->plugin_name ? info->plugin_name : "";
  if (plugin_name.empty() || path.filename().string() != "qd_" + plugin_name + ".so")
    throw PluginError(where + ": plugin calls itself '" + plugin_name + "', so its file must be named qd_" +
                      plugin_name + ".so");
  // 6. Components: well-formed and unique inside the plugin. A name an earlier library already
  //    provides is shadowed: only that component is left out, never the library's others.
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
