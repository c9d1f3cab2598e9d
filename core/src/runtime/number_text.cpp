#include "runtime/number_text.hpp"

#include <charconv>
#include <cmath>

namespace qd::runtime {

void append_number(std::string& out, double v) {
  if (std::isnan(v)) {
    out += "nan";
    return;
  }
  char buf[32];
  out.append(buf, std::to_chars(buf, buf + sizeof(buf), v).ptr);
}

std::string format_number(double v) {
  std::string s;
  append_number(s, v);
  return s;
}

void append_int(std::string& out, std::int64_t v) {
  char buf[24];
  out.append(buf, std::to_chars(buf, buf + sizeof(buf), v).ptr);
}

}  // namespace qd::runtime
