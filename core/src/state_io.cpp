#include <qd/state_io.hpp>

#include <cstring>

namespace qd::state {

void write_tag(std::ostream& out, const char (&tag)[5]) {
  out.write(tag, 4);
}

void expect_tag(std::istream& in, const char (&tag)[5]) {
  char got[5] = {0, 0, 0, 0, 0};
  if (!in.read(got, 4)) throw StateError(std::string("state blob ends before block '") + tag + "'");
  if (std::memcmp(got, tag, 4) != 0)
    throw StateError(std::string("state blob has block '") + got + "' where '" + tag + "' was expected");
}

void write_string(std::ostream& out, const std::string& s) {
  write<std::uint64_t>(out, s.size());
  out.write(s.data(), static_cast<std::streamsize>(s.size()));
}

std::string read_string(std::istream& in) {
  const auto n = read<std::uint64_t>(in);
  if (n > (1u << 30)) throw StateError("state blob has an implausible string size");
  const std::vector<char> chars = detail::read_elements<char>(in, n);
  return {chars.begin(), chars.end()};
}

}  // namespace qd::state
