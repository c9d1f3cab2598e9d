// Plugin discovery and loading (host side). The only code that touches Boost.DLL.
#pragma once

#include <qd/config.hpp>
#include <qd/plugin.hpp>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace qd::runtime {

// Deleter that keeps the plugin library mapped while the object lives: the destructor (plugin
// code) runs first, then the library reference is dropped. Objects therefore outlive the registry
// safely, whatever the destruction order.
struct LibraryHoldingDeleter {
  std::shared_ptr<const void> library;
  void operator()(const Component* c) const noexcept { delete c; }
};
template <class T>
using Owned = std::unique_ptr<T, LibraryHoldingDeleter>;

// A plugin library found on the search path. discover() reads what it declares in a probe process
// and loads it into qdrun only when one of its components is constructed, so a run loads the
// libraries it uses and no other; load() loads it at once.
struct LoadedPlugin {
  std::shared_ptr<const void> library;  // a boost::dll::shared_library, type-erased; null until loaded
  std::string path;
  const PluginInfo* info = nullptr;        // what it declares (the probe's copy, or its own once loaded)
  const PluginInfo* own_info = nullptr;    // the loaded library's own (null until loaded)
  std::shared_ptr<const void> probe_copy;  // owns `info` when a probe process read it
};

struct ComponentEntry {
  const ComponentInfo* info = nullptr;
  std::shared_ptr<LoadedPlugin> plugin;
};

// A library found in the search path and refused, with what is known of its contents.
struct Rejection {
  std::string path;
  std::string reason;  // one line, starting with the path
  // Whether the file is a plugin at all (it exports the entry symbol), and, when its information
  // could be read safely (ABI version and struct size matched), the component names it offers.
  bool is_plugin = false;
  bool names_known = false;
  std::vector<std::string> names;

  // Whether this library might have provided `name`, had it loaded.
  bool could_provide(const std::string& name) const;
};

// A component left out because a library earlier in the search path provides the same name.
struct Shadowed {
  std::string name;
  Kind kind = Kind::kMutator;
  std::string path;    // the library whose component is left out
  std::string winner;  // the library that provides the name
};

// Where a search directory comes from: the user (--plugin-path, QD_PLUGIN_PATH, [plugins]), which
// a run records in its config.toml, or the executable itself (its own plugin directory).
enum class DirOrigin { kUser, kOwn };

class Registry {
 public:
  // Directories in precedence order (first hit wins for a component name).
  void add_search_dir(const std::filesystem::path& dir, DirOrigin origin = DirOrigin::kUser);
  const std::vector<std::filesystem::path>& search_dirs() const noexcept { return dirs_; }
  // The user's directories, absolute, in search order.
  std::vector<std::string> user_dirs() const;

  // Finds every qd_*.so in the search directories and reads what it declares in a probe process of
  // its own (forked): a library whose constructors or entry function crash, hang or call exit()
  // ends only that process. Libraries that fail a check are recorded in rejected() instead of
  // throwing, so one stale or hostile file does not block unrelated experiments, --list included.
  // Nothing is loaded into this process until a component is constructed (create()). Entries
  // named like plugins that are no regular files (a dangling symlink, a FIFO) are recorded too.
  // Throws qd::SystemError when the system refuses what loading needs (no process, descriptor or
  // address space left): that is no verdict on the library.
  void discover();

  // Loads one library into this process at once and registers its components. Throws
  // qd::PluginError naming the path and the failed check. A component whose name an earlier library
  // provides is left out (shadowed()), the library's other components are registered.
  std::shared_ptr<LoadedPlugin> load(const std::filesystem::path& path);

  const ComponentEntry* find(const std::string& name) const;
  // Throws qd::InputError naming the kind and the known components, followed by one line per
  // rejected library that could have provided the name.
  const ComponentEntry& require(const std::string& name, Kind kind) const;

  const std::vector<ComponentEntry>& components() const noexcept { return components_; }
  const std::vector<std::shared_ptr<LoadedPlugin>>& plugins() const noexcept { return plugins_; }
  const std::vector<Rejection>& rejected() const noexcept { return rejected_; }
  const std::vector<Shadowed>& shadowed() const noexcept { return shadowed_; }
  // One line per (library, shadowing library) pair, naming both and the names left out.
  std::vector<std::string> warnings() const;

  // Constructs a component (loading its library into this process first, if discover() only
  // probed it); the result keeps its library loaded. Exceptions from the factory come back as
  // qd::ConfigError (with the key) or qd::PluginError naming the component and library.
  template <class T>
  Owned<T> create(const ComponentEntry& entry, const Config& config, const BuildContext& ctx) const {
    Component* raw = construct(entry, config, ctx);
    T* typed = dynamic_cast<T*>(raw);
    if (!typed) {
      destroy(raw, entry);
      throw_wrong_type(entry);
    }
    return Owned<T>(typed, LibraryHoldingDeleter{entry.plugin->library});
  }

 private:
  std::shared_ptr<LoadedPlugin> load(const std::filesystem::path& path, Rejection& seen);
  std::shared_ptr<LoadedPlugin> add(const std::filesystem::path& path, const PluginInfo* info,
                                    std::shared_ptr<const void> library, std::shared_ptr<const void> probe_copy);
  Component* construct(const ComponentEntry& entry, const Config& config, const BuildContext& ctx) const;
  static void destroy(Component* c, const ComponentEntry& entry) noexcept;
  [[noreturn]] static void throw_wrong_type(const ComponentEntry& entry);

  std::vector<std::filesystem::path> dirs_;
  std::vector<DirOrigin> origins_;
  std::vector<std::shared_ptr<LoadedPlugin>> plugins_;
  std::vector<ComponentEntry> components_;
  std::vector<Rejection> rejected_;
  std::vector<Shadowed> shadowed_;
};

// The executable's own plugin directory, <exe>/../lib/qd/plugins (the build tree mirrors the
// install tree, so this is right for build/bin/qdrun too).
std::filesystem::path installed_plugin_dir();
// The build tree's plugin directory, but only for an executable that runs from that build tree's
// bin directory; empty otherwise, so an installed qdrun never loads plugins of the tree it was
// built in.
std::filesystem::path build_tree_plugin_dir();

}  // namespace qd::runtime
