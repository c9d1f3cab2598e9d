// Little helpers for save()/load() of component state: raw little-endian PODs and Eigen matrices,
// with a tag per block so that a mismatched blob fails loudly (qd::StateError) instead of
// being silently misread.
#pragma once

#include <qd/errors.hpp>
#include <qd/export.hpp>
#include <qd/types.hpp>

#include <algorithm>
#include <cstdint>
#include <istream>
#include <ostream>
#include <string>
#include <type_traits>
#include <vector>

namespace qd::state {

template <class T>
void write(std::ostream& out, const T& v) {
  static_assert(std::is_trivially_copyable_v<T>);
  out.write(reinterpret_cast<const char*>(&v), sizeof(T));
}

template <class T>
T read(std::istream& in) {
  static_assert(std::is_trivially_copyable_v<T>);
  T v{};
  if (!in.read(reinterpret_cast<char*>(&v), sizeof(T))) throw StateError("state blob ends early");
  return v;
}

// A 4-character tag that marks the start of a block.
QD_EXPORT void write_tag(std::ostream& out, const char (&tag)[5]);
QD_EXPORT void expect_tag(std::istream& in, const char (&tag)[5]);

QD_EXPORT void write_string(std::ostream& out, const std::string& s);
QD_EXPORT std::string read_string(std::istream& in);

template <class T>
void write_vector(std::ostream& out, const std::vector<T>& v) {
  static_assert(std::is_trivially_copyable_v<T>);
  write<std::uint64_t>(out, v.size());
  if (!v.empty())
    out.write(reinterpret_cast<const char*>(v.data()), static_cast<std::streamsize>(v.size() * sizeof(T)));
}

namespace detail {
// n elements, allocated as they arrive (16 MiB at a time): a count the blob does not hold fails as
// "ends early" after at most one chunk, never as an allocation sized by a corrupt count.
template <class T>
std::vector<T> read_elements(std::istream& in, std::uint64_t n) {
  static_assert(std::is_trivially_copyable_v<T>);
  static_assert(sizeof(T) <= (std::size_t{1} << 24));
  constexpr std::uint64_t kChunk = (std::uint64_t{1} << 24) / sizeof(T);
  std::vector<T> v;
  for (std::uint64_t done = 0; done < n;) {
    const std::uint64_t k = n - done < kChunk ? n - done : kChunk;
    v.resize(static_cast<std::size_t>(done + k));
    if (!in.read(reinterpret_cast<char*>(v.data() + done), static_cast<std::streamsize>(k * sizeof(T))))
      throw StateError("state blob ends early");
    done += k;
  }
  return v;
}
}  // namespace detail

template <class T>
std::vector<T> read_vector(std::istream& in) {
  const auto n = read<std::uint64_t>(in);
  if (n > (std::uint64_t{1} << 40) / sizeof(T)) throw StateError("state blob has an implausible vector size");
  return detail::read_elements<T>(in, n);
}

template <class Derived>
void write_matrix(std::ostream& out, const Eigen::PlainObjectBase<Derived>& m) {
  using Scalar = typename Derived::Scalar;
  write<std::int64_t>(out, m.rows());
  write<std::int64_t>(out, m.cols());
  write<std::uint32_t>(out, sizeof(Scalar));
  if (m.size())
    out.write(reinterpret_cast<const char*>(m.data()), static_cast<std::streamsize>(m.size() * sizeof(Scalar)));
}

template <class Derived>
void read_matrix(std::istream& in, Eigen::PlainObjectBase<Derived>& m) {
  using Scalar = typename Derived::Scalar;
  const auto rows = read<std::int64_t>(in);
  const auto cols = read<std::int64_t>(in);
  const auto width = read<std::uint32_t>(in);
  // (rows > limit / cols, not rows * cols > limit: a corrupt header must not overflow the product.)
  if (rows < 0 || cols < 0 || width != sizeof(Scalar) || (cols > 0 && rows > (std::int64_t{1} << 36) / cols))
    throw StateError("state blob has a malformed matrix header");
  const std::vector<Scalar> data = detail::read_elements<Scalar>(in, static_cast<std::uint64_t>(rows * cols));
  m.resize(rows, cols);
  std::copy(data.begin(), data.end(), m.data());  // in storage order, as written
}

}  // namespace qd::state
