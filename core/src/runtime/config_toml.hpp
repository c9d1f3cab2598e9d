// What the configuration stages share on the TOML side (config_document.cpp, config_schema.cpp,
// experiment.cpp, cost_model.cpp): the parsed document, the place of a node for messages, and
// writing values back as TOML text. toml++ types never leave these files; every other header is
// free of them.
#pragma once

#include "runtime/config_document.hpp"
#include "runtime/config_schema.hpp"

#include <qd/config.hpp>

#include <toml++/toml.h>

#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace qd::runtime {

// The component type in effect where a key of a component table was set: the type in the same
// file's table or, failing that, in the layers below it. A key set under another type than the
// final one came with a component that an include or --set replaced. `known` is false for keys of
// --set (always validated) and for keys with no type anywhere below them yet.
struct KeyOrigin {
  std::string type;
  bool known = false;
};
using KeyOrigins = std::map<std::string, std::map<std::string, KeyOrigin>>;  // table -> key -> origin

struct Document::Impl {
  toml::table root;
  std::filesystem::path file;
  KeyOrigins origins;
};

// Text for a message: control characters (a newline in a path given on the command line) shown
// as escapes, so a message stays one line.
std::string printable(const std::string& text);
bool has_control_character(const std::string& text);

// TOML text of a value, numbers in their shortest exact form, for config.toml and for messages.
std::string value_text(const toml::node& n);
// A resolved configuration as TOML: each table's values, then its sub-tables under [headers].
std::string toml_text(const toml::table& t);

// "file:line:column", or the command-line option a value came from.
std::string location(const toml::source_region& src);
std::string location(const toml::node& n);
[[noreturn]] void fail_at(const toml::node& n, const std::string& msg);

// root[name] as a table (null when absent); anything else there is an error at its place.
const toml::table* sub_table(const toml::table& root, const char* name);

// " (did you mean 'x'?)" for a near miss among `known`, else "".
std::string suggestion(const std::string& key, const std::vector<std::string>& known);
// "a, b, c", or "(none)".
std::string join(const std::vector<std::string>& v);

// The schema stage (config_schema.cpp): validates `tbl` (null = all defaults) against `specs`;
// `skip` keys are handled by the caller. `owner` names who declares the keys, for messages.
Config validate_table(const toml::table* tbl, const std::string& table, const ParamSpec* specs, std::size_t count,
                      const std::string& owner, const std::vector<std::string>& skip = {});
// Writes every key of `specs` with its value in `cfg` to `out` (a resolved table).
void put_config(toml::table& out, const Config& cfg, const ParamSpec* specs, std::size_t count);
// The core tables of `root` checked and typed into `settings` (`file` names a run without a name),
// and their resolved tables put in `resolved`.
void resolve_core_tables(const toml::table& root, const std::filesystem::path& file, ExperimentSettings& settings,
                         toml::table& resolved);

}  // namespace qd::runtime
