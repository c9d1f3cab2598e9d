// Numbers as the run's text files write them (metrics.csv, archive snapshots, fault-offspring.csv):
// the shortest text that reads back to the same value.
#pragma once

#include <cstdint>
#include <string>

namespace qd::runtime {

// Shortest text that reads back to the same double (std::to_chars); NaN is "nan", infinities
// "inf" and "-inf", as pandas reads them.
void append_number(std::string& out, double v);
std::string format_number(double v);
void append_int(std::string& out, std::int64_t v);

}  // namespace qd::runtime
