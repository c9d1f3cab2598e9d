// Error types and the aborting invariant check.
//
// Three kinds of failure, three mechanisms (docs/plugin-guide.md, "Errors"):
//  * setup-time problems the user can fix (bad TOML, unknown component, broken plugin):
//    exceptions derived from qd::Error, caught once by qdrun and reported with exit code 2;
//  * expected per-evaluation outcomes (a diverged simulation, a NaN action): status values
//    in qd::Trace, never exceptions;
//  * broken invariants (bugs): QD_CHECK, which prints file and line and aborts.
#pragma once

#include <qd/export.hpp>

#include <stdexcept>
#include <string>

namespace qd {

class QD_EXPORT Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what);
  ~Error() override;
};

// The user's input is wrong (experiment file, command line, output directory). Exit code 2.
class QD_EXPORT InputError : public Error {
 public:
  explicit InputError(const std::string& what);
  ~InputError() override;
};

// A configuration value is wrong. `key` is the key inside the component's table (for example
// "sigma"); the core prefixes file, line, column and table before showing it to the user.
class QD_EXPORT ConfigError : public InputError {
 public:
  ConfigError(std::string key, const std::string& what);
  ~ConfigError() override;
  const std::string& key() const noexcept { return key_; }

 private:
  std::string key_;
};

// A shared library could not be used as a plugin. Always names the library path.
class QD_EXPORT PluginError : public InputError {
 public:
  explicit PluginError(const std::string& what);
  ~PluginError() override;
};

// A checkpoint or state blob could not be read back.
class QD_EXPORT StateError : public Error {
 public:
  explicit StateError(const std::string& what);
  ~StateError() override;
};

[[noreturn]] QD_EXPORT void check_failed(const char* expr, const char* file, int line, const char* msg);

}  // namespace qd

// Aborts with file and line when an invariant is broken. Active in every build type: the checks
// sit outside inner loops, and a silently corrupted archive costs researchers far more.
#define QD_CHECK(cond, msg) ((cond) ? static_cast<void>(0) : ::qd::check_failed(#cond, __FILE__, __LINE__, (msg)))
