#include <qd/errors.hpp>

#include <cstdio>
#include <cstdlib>

namespace qd {

Error::Error(const std::string& what) : std::runtime_error(what) {}
Error::~Error() = default;
InputError::InputError(const std::string& what) : Error(what) {}
InputError::~InputError() = default;
ConfigError::ConfigError(std::string key, const std::string& what) : InputError(what), key_(std::move(key)) {}
ConfigError::~ConfigError() = default;
PluginError::PluginError(const std::string& what) : InputError(what) {}
PluginError::~PluginError() = default;
SystemError::SystemError(const std::string& what) : Error(what) {}
SystemError::~SystemError() = default;
StateError::StateError(const std::string& what) : Error(what) {}
StateError::~StateError() = default;

void check_failed(const char* expr, const char* file, int line, const char* msg) {
  std::fprintf(stderr, "qd: internal invariant broken at %s:%d: %s (%s)\n", file, line, msg, expr);
  std::fflush(stderr);
  std::abort();
}

}  // namespace qd
