// One plugin library in this process: what can be judged of its file without running its code,
// loading it with every check of the plugin contract, and keeping it loaded (registry.cpp decides
// which libraries; plugin_probe.hpp reads one in a process of its own first).
#pragma once

#include "runtime/registry.hpp"

#include <vector>  // boost/dll/library_info.hpp needs it first with BOOST_DLL_USE_STD_FS (Boost 1.74)

#include <boost/dll/shared_library.hpp>

#include <filesystem>
#include <memory>
#include <string>
#include <system_error>

namespace qd::runtime {

// Whether a directory entry is named like a plugin library (qd_*.so).
bool looks_like_plugin_file(const std::filesystem::path& p);

// Why a directory entry named like a plugin is no file to load (`status_error`: what following it
// reported).
std::string not_a_library(const std::filesystem::path& path, const std::error_code& status_error);

// A library opened in this process and checked: the plugin contract's every check passed.
struct Opened {
  std::shared_ptr<boost::dll::shared_library> library;
  const PluginInfo* info = nullptr;
};

// What can be judged of `path` without running any of its code: a regular ELF file of this word
// size that exports the entry symbol. Reading the ELF symbol table first means a shared library
// that is not a plugin is never dlopen'ed (so its static initialisers never run).
void check_file(const std::filesystem::path& path, Rejection& seen);
// Loads `path` (which check_file() accepted) into this process and checks what it declares.
Opened open_checked(const std::filesystem::path& path, Rejection& seen);
// Keeps an accepted library loaded for good (see plugin_library.cpp).
void pin(const std::filesystem::path& path);

}  // namespace qd::runtime
