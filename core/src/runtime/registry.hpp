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

struct LoadedPlugin {
  std::shared_ptr<const void> library;  // a boost::dll::shared_library, type-erased
  std::string path;
  const PluginInfo* info = nullptr;
};

struct ComponentEntry {
  const ComponentInfo* info = nullptr;
  std::shared_ptr<LoadedPlugin> plugin;
};

struct Rejection {
  std::string path;
  std::string reason;
};

class Registry {
 public:
  // Directories in precedence order (first hit wins for a component name).
  void add_search_dir(const std::filesystem::path& dir);
  const std::vector<std::filesystem::path>& search_dirs() const noexcept { return dirs_; }

  // Loads every qd_*.so in the search directories. Libraries that fail a check are recorded in
  // rejected() instead of throwing, so one stale file does not block unrelated experiments.
  void discover();

  // Loads one library and registers its components. Throws qd::PluginError naming the path and the
  // failed check.
  std::shared_ptr<LoadedPlugin> load(const std::filesystem::path& path);

  const ComponentEntry* find(const std::string& name) const;
  // Throws qd::InputError naming the kind, the known components and any rejected libraries.
  const ComponentEntry& require(const std::string& name, Kind kind) const;

  const std::vector<ComponentEntry>& components() const noexcept { return components_; }
  const std::vector<std::shared_ptr<LoadedPlugin>>& plugins() const noexcept { return plugins_; }
  const std::vector<Rejection>& rejected() const noexcept { return rejected_; }

  // Constructs a component; the result keeps its library loaded. Exceptions from the factory come
  // back as qd::ConfigError (with the key) or qd::PluginError naming the component and library.
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
  Component* construct(const ComponentEntry& entry, const Config& config, const BuildContext& ctx) const;
  static void destroy(Component* c, const ComponentEntry& entry) noexcept;
  [[noreturn]] static void throw_wrong_type(const ComponentEntry& entry);

  std::vector<std::filesystem::path> dirs_;
  std::vector<std::shared_ptr<LoadedPlugin>> plugins_;
  std::vector<ComponentEntry> components_;
  std::vector<Rejection> rejected_;
};

// The build-tree plugin directory baked in at compile time, and <exe>/../lib/qd/plugins.
std::filesystem::path build_tree_plugin_dir();
std::filesystem::path installed_plugin_dir();

}  // namespace qd::runtime
