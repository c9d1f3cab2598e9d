// The plugin contract: what a plugin library exports and what the host checks before using it.
//
// A plugin library exports exactly one symbol, the Boost.DLL alias `qd_plugin_entry_v1`, a
// function returning a pointer to a static PluginInfo. The host checks, in order: the alias is
// present; abi_version == kPluginAbiVersion; info_size == sizeof(PluginInfo); the build fingerprint
// equals the core's; the file is named qd_<plugin_name>.so; component names are unique; each
// created object has the dynamic type its kind promises. Objects made by a plugin keep its library
// loaded; libraries are never unloaded during a run.
//
// Plugin authors write:
//
//   #include <qd/plugin.hpp>
//   class MyMutator final : public qd::Mutator { public: MyMutator(const qd::Config&, const qd::BuildContext&); ... };
//   constexpr qd::ParamSpec kMyParams[] = {qd::param_float("sigma", "0.1", 0.0, qd::kUnbounded, "step size")};
//   QD_PLUGIN("my_plugin", "1.0.0",
//             qd::component<MyMutator>(qd::Kind::kMutator, "my-mutator", "One-line summary.", kMyParams))
//
// Any change under core/include/qd/ changes the build fingerprint (it hashes the headers); bump
// kPluginAbiVersion too when the layout of PluginInfo or ComponentInfo changes, or when a component
// interface changes so that an old plugin's source no longer fits, so the refusal names the cause.
#pragma once

#include <qd/component.hpp>
#include <qd/config.hpp>
#include <qd/descriptor.hpp>
#include <qd/environment.hpp>
#include <qd/errors.hpp>
#include <qd/export.hpp>
#include <qd/mutator.hpp>
#include <qd/representation.hpp>
#include <qd/version.hpp>

#ifndef BOOST_DLL_USE_STD_FS
#define BOOST_DLL_USE_STD_FS  // plugins and host must agree; without it Boost.System symbols leak
#endif
#include <boost/dll/alias.hpp>

#include <cstdint>

namespace qd {

// 4: RolloutBatch::params is a row-major `const double*` (was `const Matrix*`).
// 5: Representation::estimate_fit_seconds (a new virtual member).
// 6: environments with persistent worlds (EnvironmentInfo::persistent_worlds, RolloutBatch::world,
//    Environment::save/load); CHANGELOG.md.
// 7: GridSpec::labels (names of a descriptor's bins, written to grid.toml); mutator feedback per
//    offspring (Feedback::results, was `outcomes`); EnvironmentInfo declares fitness and direct
//    parameter vectors; GridSpec::centroids (CVT); BuildContext::batch, wrapped, stored_grid;
//    ComponentInfo::flags (descriptor adapters). CHANGELOG.md has the migrations.
// 8: Offspring::mixing_ratio is the metric kMixingRatio; FitContext::log (a TrainingLog) replaces
//    FitContext::run_dir and Representation::log_files(); an environment's default descriptor is
//    declared in its ComponentInfo (qd::environment<T>), no longer in EnvironmentInfo;
//    Representation::estimate_fit_seconds moves to the optional qd::FitTimeEstimate
//    (<qd/planning.hpp>). CHANGELOG.md has the migrations.
inline constexpr std::uint32_t kPluginAbiVersion = 8;

enum class Kind : std::uint32_t { kEnvironment = 1, kDescriptor = 2, kRepresentation = 3, kMutator = 4 };
QD_EXPORT const char* to_string(Kind kind) noexcept;

// Factories return a raw pointer only at this boundary; the host wraps it at once in an owner
// that keeps the library loaded. May throw qd::ConfigError (or anything: the host reports it).
using CreateFn = Component* (*)(const Config&, const BuildContext&);

// ComponentInfo::flags.
inline constexpr std::uint32_t kWrapsDescriptor = 1u;  // a descriptor adapter: wraps another descriptor

struct ComponentInfo {
  Kind kind;
  const char* name;
  const char* summary;
  const ParamSpec* params;
  std::uint32_t param_count;
  CreateFn create;
  std::uint32_t flags;  // kWrapsDescriptor
  // Environments: the descriptor used when the experiment's [descriptor] names none (nullptr:
  // none, the experiment must name one). Declared here, not by a built environment, so that an
  // experiment file resolves completely before any plugin object exists.
  const char* default_descriptor;
};

// Layout frozen for a given abi_version; abi_version must stay the first field.
struct PluginInfo {
  std::uint32_t abi_version;
  std::uint32_t info_size;
  const char* build_fingerprint;
  const char* plugin_name;
  const char* plugin_version;
  std::uint32_t component_count;
  const ComponentInfo* components;
};

using PluginEntryFn = const PluginInfo* (*)();

template <class T, std::size_t N>
ComponentInfo component(Kind kind, const char* name, const char* summary, const ParamSpec (&params)[N]) {
  return {kind,
          name,
          summary,
          params,
          static_cast<std::uint32_t>(N),
          [](const Config& c, const BuildContext& b) -> Component* { return new T(c, b); },
          0u,
          nullptr};
}
template <class T>
ComponentInfo component(Kind kind, const char* name, const char* summary) {
  return {kind,    name,   summary,
          nullptr, 0u,     [](const Config& c, const BuildContext& b) -> Component* { return new T(c, b); },
          0u,      nullptr};
}
// An environment and its default descriptor (a descriptor component's name, in this plugin or
// another; nullptr: none).
template <class T, std::size_t N>
ComponentInfo environment(const char* name, const char* summary, const ParamSpec (&params)[N],
                          const char* default_descriptor) {
  ComponentInfo info = component<T>(Kind::kEnvironment, name, summary, params);
  info.default_descriptor = default_descriptor;
  return info;
}
template <class T>
ComponentInfo environment(const char* name, const char* summary, const char* default_descriptor) {
  ComponentInfo info = component<T>(Kind::kEnvironment, name, summary);
  info.default_descriptor = default_descriptor;
  return info;
}
// A descriptor that wraps another ([descriptor] type = NAME, the wrapped one in [descriptor.wraps],
// by default the environment's own): the core builds the wrapped descriptor first and hands it over
// in BuildContext::wrapped.
template <class T, std::size_t N>
ComponentInfo descriptor_adapter(const char* name, const char* summary, const ParamSpec (&params)[N]) {
  ComponentInfo info = component<T>(Kind::kDescriptor, name, summary, params);
  info.flags = kWrapsDescriptor;
  return info;
}

}  // namespace qd

#define QD_PLUGIN(NAME, VERSION, ...)                                                                          \
  namespace {                                                                                                  \
  const ::qd::PluginInfo* qd_plugin_entry_impl() {                                                             \
    static const ::qd::ComponentInfo components[] = {__VA_ARGS__};                                             \
    static const ::qd::PluginInfo info{::qd::kPluginAbiVersion,                                                \
                                       static_cast<std::uint32_t>(sizeof(::qd::PluginInfo)),                   \
                                       QD_BUILD_FINGERPRINT,                                                   \
                                       NAME,                                                                   \
                                       VERSION,                                                                \
                                       static_cast<std::uint32_t>(sizeof(components) / sizeof(components[0])), \
                                       components};                                                            \
    return &info;                                                                                              \
  }                                                                                                            \
  }                                                                                                            \
  BOOST_DLL_ALIAS(qd_plugin_entry_impl, qd_plugin_entry_v1)
