// The plugin search path from qdrun's command line, environment and files (cli.hpp).
#include "cli.hpp"

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <system_error>

namespace qd::app {
namespace fs = std::filesystem;
using runtime::build_tree_plugin_dir;
using runtime::DirOrigin;
using runtime::installed_plugin_dir;
using runtime::Registry;

namespace {
std::vector<std::string> split_path_list(const char* text) {
  std::vector<std::string> out;
  if (!text) return out;
  std::string s = text;
  for (std::size_t pos = 0;;) {
    const std::size_t c = s.find(':', pos);
    const std::string part = s.substr(pos, c == std::string::npos ? std::string::npos : c - pos);
    if (!part.empty()) out.push_back(part);
    if (c == std::string::npos) break;
    pos = c + 1;
  }
  return out;
}

}  // namespace

std::string not_a_directory(const std::string& dir) {
  std::error_code ec;
  const fs::file_status st = fs::status(dir, ec);
  if (fs::is_directory(st)) return "";
  if (ec && ec != std::errc::no_such_file_or_directory) return "cannot be read (" + ec.message() + ")";
  if (!fs::exists(st)) return "does not exist";
  return "is not a directory";
}

void setup_registry(Registry& reg, const Cli& cli, const std::vector<std::string>& from_file,
                    const std::vector<std::string>& recorded) {
  // A directory the user names that is not there is a typo or a stale path: --plugin-path is an
  // error (check_options), the others are said once.
  auto warn_missing = [&](const std::string& dir, const std::string& from) {
    if (const std::string why = not_a_directory(dir); !cli.quiet && !why.empty())
      std::fprintf(stderr, "qdrun: warning: plugin directory %s (%s) %s\n", dir.c_str(), from.c_str(), why.c_str());
  };
  for (const auto& p : cli.plugin_paths) reg.add_search_dir(p);
  for (const auto& p : split_path_list(std::getenv("QD_PLUGIN_PATH"))) {
    warn_missing(p, "QD_PLUGIN_PATH");
    reg.add_search_dir(p);
  }
  for (const auto& p : from_file) {
    warn_missing(p, "[plugins] path");
    reg.add_search_dir(p);
  }
  for (const auto& p : recorded) reg.add_search_dir(p);
  reg.add_search_dir(installed_plugin_dir(), DirOrigin::kOwn);
  reg.add_search_dir(build_tree_plugin_dir(), DirOrigin::kOwn);
  reg.discover();
  if (!cli.quiet)
    for (const auto& w : reg.warnings()) std::fprintf(stderr, "qdrun: warning: %s\n", w.c_str());
}

}  // namespace qd::app
