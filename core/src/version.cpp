#include <qd/version.hpp>

#include "qd_git_revision.h"  // generated at build time

namespace qd {
const char* build_fingerprint() noexcept {
  return QD_BUILD_FINGERPRINT;
}
const char* version_string() noexcept {
  return QD_VERSION_STRING;
}
const char* git_revision() noexcept {
  return QD_GIT_REVISION;
}
const char* instruction_set() noexcept {
  return QD_INSTRUCTION_SET;  // defined by core/CMakeLists.txt
}
}  // namespace qd
