// Helpers for the unit tests that check what the runtime writes to disk.
#pragma once

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace qd::test {

// A file's whole content (empty if it cannot be read).
inline std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace qd::test
