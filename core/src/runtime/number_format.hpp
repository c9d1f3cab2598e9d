// Shortest round-trip text of a double, the same characters as std::to_chars(first, last, v).
//
// archive.csv holds every parameter of every elite (2.8 million numbers for the 32x32 arm), so
// its formatting is most of the cost of writing it. This formatter takes about 30 ns per number
// where libstdc++'s to_chars takes 43 (bench/number_format.cpp times both on the same values).
// It follows the idea of Schubfach (R. Giulietti, "The Schubfach way to render doubles", 2020):
// scale the rounding interval of v by a 128-bit power of ten, keep two extra bits and round to
// odd, so that the few comparisons that decide the shortest decimal are exact. Where exactness
// cannot be shown cheaply (v*10^-k within 2^-64 of an integer, which holds for short decimals
// such as 0.5 or 3) and for large integers printed in fixed notation, it calls std::to_chars, so
// every output is std::to_chars' output.
#pragma once

#include <cstddef>

namespace qd::runtime {

// Bytes `out` must have room for: the text is at most 25 characters, but the digits are moved
// with fixed-size copies that may scribble (and then overwrite) up to this many bytes.
constexpr std::size_t kNumberBufferBytes = 64;

// Writes the shortest text that reads back to `v` at `out` and returns its end. NaN is written
// "nan", infinities "inf" and "-inf" (as pandas reads them).
char* write_number(double v, char* out) noexcept;

namespace detail {
// floor(log10(2^q)), or floor(log10(3/4 2^q)), exact for the exponents of doubles (tested).
int floor_log10_pow2(int q, bool three_quarters) noexcept;
}  // namespace detail

}  // namespace qd::runtime
