#include "runtime/plugin_library.hpp"

#include <qd/errors.hpp>
#include <qd/version.hpp>

#include <boost/dll/library_info.hpp>

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

bool looks_like_plugin_file(const fs::path& p) {
  const std::string name = p.filename().string();
  return name.rfind("qd_", 0) == 0 && p.extension() == ".so";
}

// Why a directory entry named like a plugin is no file to load (`status_error`: what following it
// reported).
std::string not_a_library(const fs::path& path, const std::error_code& status_error) {
  std::error_code ec;
  const fs::file_status own = fs::symlink_status(path, ec);
  if (fs::is_symlink(own)) {
    if (status_error == std::errc::too_many_symbolic_link_levels) return "a symbolic link loop, not a shared library";
    if (status_error) return "a symbolic link to nothing (" + status_error.message() + "), not a shared library";
  }
  const fs::file_status st = fs::status(path, ec);
  if (fs::is_directory(st)) return "a directory, not a shared library";
  if (fs::is_fifo(st)) return "a FIFO, not a shared library";
  if (fs::is_character_file(st) || fs::is_block_file(st)) return "a device, not a shared library";
  if (fs::is_socket(st)) return "a socket, not a shared library";
  return "not a regular file, so not a shared library";
}

// What can be judged of `path` without running any of its code: a regular ELF file of this word
// size that exports the entry symbol. Reading the ELF symbol table first means a shared library
// that is not a plugin is never dlopen'ed (so its static initialisers never run).
void check_file(const fs::path& path, Rejection& seen) {
  const std::string where = path.string();
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw PluginError(where + ": no such plugin file");
  if (const std::string junk = not_elf_reason(path); !junk.empty()) throw PluginError(where + ": " + junk);
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
}

// Loads `path` (which check_file() accepted) into this process and checks what it declares.
Opened open_checked(const fs::path& path, Rejection& seen) {
  const std::string where = path.string();
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
    // No descriptor or memory left to map it (ulimit -n, ulimit -v): the system's failure, not the
    // library's (exit 4), and never a silent "unknown component" for every library.
    for (const int shortage : {EMFILE, ENFILE, ENOMEM})
      if (reason.find(std::strerror(shortage)) != std::string::npos)
        throw SystemError(where + ": cannot be loaded: " + reason);
    if (reason.find("failed to map segment") != std::string::npos)
      throw SystemError(where + ": cannot be loaded: " + reason + " (too little address space: ulimit -v?)");
    throw PluginError(where + ": cannot be loaded: " + reason);
  }
  // The entry symbol is an alias: a variable holding the entry function's address. It is read as
  // that variable, so a null one is refused before it is called (get_alias would bind a reference
  // to it).
  PluginEntryFn entry = nullptr;
  try {
    const void* const address = lib->get<const void*>(kEntrySymbol);
    static_assert(sizeof(address) == sizeof(entry), "function and object pointers differ in size");
    std::memcpy(&entry, &address, sizeof(entry));
  } catch (const std::exception& e) {
    throw PluginError(where + ": cannot resolve '" + kEntrySymbol + "': " + e.what());
  }
  if (!entry) throw PluginError(where + ": its entry symbol '" + kEntrySymbol + "' is null");
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
  // 6. Components: well-formed and unique inside the plugin.
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
    if (c.param_count > 0 && !c.params) throw PluginError(where + ": component '" + c.name + "' has no parameter list");
    if (c.default_descriptor && (c.kind != Kind::kEnvironment || !*c.default_descriptor))
      throw PluginError(where + ": component '" + c.name +
                        "' declares an empty default descriptor or is no environment");
    for (std::uint32_t k = 0; k < c.param_count; ++k)
      if (!c.params[k].key || !c.params[k].default_value)
        throw PluginError(where + ": component '" + c.name + "' declares a parameter without a name or default");
  }
  return {lib, info};
}

// An accepted plugin is never unloaded, not even at exit: its dependencies (libgomp for the
// autoencoder) keep their static state, and no destructor of a plugin-made object can outlive its
// code. Promoting the loaded library to RTLD_NODELETE does that; the extra handle is never closed.
void pin(const fs::path& path) {
  if (!::dlopen(path.c_str(), RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE))
    throw PluginError(path.string() + ": cannot pin the loaded plugin: " + ::dlerror());
}

}  // namespace qd::runtime
