// Configuration, stage 1 of 3: the document. An experiment file as read: its includes layered
// (the including file's keys win), command-line overrides applied, and for every key of a component
// table the component it was written for. No schema yet: that is config_schema.hpp, and resolving
// components is experiment.hpp. docs/design.md, "Configuration and planning".
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace qd::runtime {

// An experiment file, a run's config.toml or provenance: far beyond any real one.
inline constexpr std::uint64_t kMaxTomlBytes = 16 << 20;

// Raw parsed document (PIMPL around toml::table so no TOML type leaks into headers).
class Document {
 public:
  Document();
  ~Document();
  Document(Document&&) noexcept;
  Document& operator=(Document&&) noexcept;

  // Reads `file`, following `include = [...]` (paths relative to the including file; the including
  // file's keys win). Throws qd::InputError with file:line:column on any problem.
  static Document read(const std::filesystem::path& file);
  static Document parse(const std::string& text, const std::string& source_name);

  // Applies `key.path=value`; value is a TOML number, boolean, quoted string, array or inline
  // table, and anything else (a bare word, also nan, inf and dates) is taken as a string.
  // Errors name `option` (the command-line option it came from), or "--set key.path=value".
  void apply_override(const std::string& assignment, const std::string& option = {});
  // The same for a value the caller has as a string or an integer (a path, a seed, a loop count):
  // any text, quotes and newlines included, arrives as that string. Nobody else writes TOML text.
  void set_string(const std::string& path, const std::string& value, const std::string& option = {});
  void set_integer(const std::string& path, std::int64_t value, const std::string& option = {});

  // [plugins] path entries (absolute), available before plugins are loaded.
  std::vector<std::string> plugin_paths() const;
  // [plugins] search_path entries (absolute): the user directories a run searched, as its
  // config.toml records them, so that --resume finds the same plugins.
  std::vector<std::string> recorded_search_path() const;
  std::filesystem::path file() const;

  struct Impl;
  std::unique_ptr<Impl> impl;
};

// A string as a TOML basic string ("...", with escapes): the one quoting helper.
std::string toml_string(const std::string& s);

// The keys whose values differ between two resolved configurations (TOML texts), with both
// values as TOML text ("(absent)" where a key is missing), in key order.
struct ConfigDifference {
  std::string key, before, after;
};
// Throws InputError when either text is not TOML.
std::vector<ConfigDifference> config_differences(const std::string& before, const std::string& after);
// Every value of a resolved configuration by dotted key ("mutator.sigma" -> "0.2"), whatever the
// order of its tables. Throws InputError when `toml` is not TOML (`source` names it).
std::map<std::string, std::string> config_values(const std::string& toml, const std::string& source);

// Keys --resume may change (dotted path): the budget (experiment.loops), how and where evaluations
// run ([evaluation]), what is written ([output]) and where plugins are found ([plugins]). Anything
// else would make the resumed run another experiment; experiment.name (with the seed) names the run
// directory, so a run keeps it.
bool may_change_on_resume(const std::string& key);

}  // namespace qd::runtime
