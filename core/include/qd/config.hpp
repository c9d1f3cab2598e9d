// Configuration as seen by a component: its own validated table, defaults filled in.
//
// Only the core reads TOML. A component declares its parameters as an array of ParamSpec; the core
// checks the user's table against it before the component's factory runs (unknown keys, wrong
// types, out-of-range values and unknown choices are errors naming file, line, column and key path)
// and fills in defaults. The component then reads typed values with the getters below. Cross-key
// checks belong in the component's constructor: throw qd::ConfigError{key, message} and the core
// adds the location of `key`.
#pragma once

#include <qd/export.hpp>

#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace qd {

enum class ParamType : std::uint32_t {
  kBool = 0,
  kInteger = 1,
  kFloat = 2,  // accepts TOML integers too
  kString = 3,
  kIntegerList = 4,
  kFloatList = 5,
};

QD_EXPORT const char* to_string(ParamType type) noexcept;

// One declared parameter. A plain aggregate so that plugins can keep a static array of them.
// `default_value` is TOML value syntax ("0.1", "[32, 32]", "\"reference\"", "true").
// `min`/`max` bound numbers and every list element (inclusive). `choices` lists the allowed
// strings separated by '|', or is nullptr for free text.
struct ParamSpec {
  const char* key;
  ParamType type;
  const char* default_value;
  double min;
  double max;
  const char* choices;
  const char* help;
};

inline constexpr double kUnbounded = std::numeric_limits<double>::infinity();

constexpr ParamSpec param_bool(const char* key, const char* def, const char* help) {
  return {key, ParamType::kBool, def, -kUnbounded, kUnbounded, nullptr, help};
}
constexpr ParamSpec param_int(const char* key, const char* def, double min, double max, const char* help) {
  return {key, ParamType::kInteger, def, min, max, nullptr, help};
}
constexpr ParamSpec param_float(const char* key, const char* def, double min, double max, const char* help) {
  return {key, ParamType::kFloat, def, min, max, nullptr, help};
}
constexpr ParamSpec param_string(const char* key, const char* def, const char* choices, const char* help) {
  return {key, ParamType::kString, def, -kUnbounded, kUnbounded, choices, help};
}
constexpr ParamSpec param_int_list(const char* key, const char* def, double min, double max, const char* help) {
  return {key, ParamType::kIntegerList, def, min, max, nullptr, help};
}
constexpr ParamSpec param_float_list(const char* key, const char* def, double min, double max, const char* help) {
  return {key, ParamType::kFloatList, def, min, max, nullptr, help};
}

// A component's resolved table. Getters throw qd::ConfigError for an undeclared key or a type
// that does not match the declaration (a bug in the component, reported with the key).
class QD_EXPORT Config {
 public:
  Config();
  Config(const Config&);
  Config& operator=(const Config&);
  Config(Config&&) noexcept;
  Config& operator=(Config&&) noexcept;
  ~Config();

  // The table this configuration came from, e.g. "mutator".
  const std::string& table() const noexcept;
  // "file.toml:12:9" for a key the user wrote, "default" for a default.
  std::string where(const std::string& key) const;
  bool has(const std::string& key) const noexcept;
  // True when the user wrote the key (false for a filled-in default).
  bool is_set(const std::string& key) const noexcept;

  bool get_bool(const std::string& key) const;
  std::int64_t get_int(const std::string& key) const;
  double get_float(const std::string& key) const;
  std::string get_string(const std::string& key) const;
  std::vector<std::int64_t> get_int_list(const std::string& key) const;
  std::vector<double> get_float_list(const std::string& key) const;

  // Keys in declaration order.
  std::vector<std::string> keys() const;

  // Used by the core and by tests to build configurations by hand.
  explicit Config(std::string table);
  void set_bool(const std::string& key, bool v, std::string where = "default");
  void set_int(const std::string& key, std::int64_t v, std::string where = "default");
  void set_float(const std::string& key, double v, std::string where = "default");
  void set_string(const std::string& key, std::string v, std::string where = "default");
  void set_int_list(const std::string& key, std::vector<std::int64_t> v, std::string where = "default");
  void set_float_list(const std::string& key, std::vector<double> v, std::string where = "default");
  // Parses `toml_value` as TOML value syntax into `key` with the declared type (used for defaults).
  void set_from_text(const ParamSpec& spec, const std::string& toml_value, std::string where = "default");

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// Builds a Config holding the declared defaults of `specs`; used by unit tests of components.
QD_EXPORT Config defaults_of(const ParamSpec* specs, std::size_t count, const std::string& table);
template <std::size_t N>
Config defaults_of(const ParamSpec (&specs)[N], const std::string& table) {
  return defaults_of(specs, N, table);
}

}  // namespace qd
