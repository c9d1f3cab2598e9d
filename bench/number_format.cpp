// Number formatting for archive.csv: ns per number of write_number() and of std::to_chars on the
// same values, measured alternately in one process (the fastest of --repeat rounds each).
//
//   qd_number_format [--count N] [--repeat K]
// Values: U(-1, 1), what policy parameters usually are, and doubles of uniformly random bits.
#include "runtime/number_format.hpp"

#include <qd/rng.hpp>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace {

template <class Format>
double ns_per_number(const std::vector<double>& values, Format format, std::size_t& sink) {
  char buf[qd::runtime::kNumberBufferBytes];
  const auto t0 = std::chrono::steady_clock::now();
  for (double v : values) sink += static_cast<std::size_t>(format(v, buf) - buf);
  const std::chrono::duration<double, std::nano> dt = std::chrono::steady_clock::now() - t0;
  return dt.count() / static_cast<double>(values.size());
}

}  // namespace

int main(int argc, char** argv) {
  std::size_t count = 3000000;
  int repeat = 5;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--count") count = std::stoul(argv[i + 1]);
    if (a == "--repeat") repeat = std::max(1, std::stoi(argv[i + 1]));
  }
  qd::Rng rng(1, qd::Stream::kPlugin, 0);
  std::vector<double> uniform(count), bits(count);
  rng.fill_uniform(uniform.data(), count, -1.0, 1.0);
  for (auto& v : bits) {
    do {
      const std::uint64_t b = rng.next();
      std::memcpy(&v, &b, sizeof(v));
    } while (!std::isfinite(v));
  }
  auto ours = [](double v, char* out) { return qd::runtime::write_number(v, out); };
  auto std_to_chars = [](double v, char* out) {
    return std::to_chars(out, out + qd::runtime::kNumberBufferBytes, v).ptr;
  };
  std::size_t sink = 0;
  for (const auto& [name, values] : {std::pair{"uniform(-1,1)", &uniform}, std::pair{"random bits", &bits}}) {
    double best_ours = 1e300, best_std = 1e300;
    for (int r = 0; r < repeat; ++r) {
      best_ours = std::min(best_ours, ns_per_number(*values, ours, sink));
      best_std = std::min(best_std, ns_per_number(*values, std_to_chars, sink));
    }
    std::printf("values=%s count=%zu write_number_ns=%.1f std_to_chars_ns=%.1f ratio=%.3f (best of %d)\n", name, count,
                best_ours, best_std, best_ours / best_std, repeat);
  }
  return sink == 0;
}
