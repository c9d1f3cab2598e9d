// Component state blobs (<qd/state_io.hpp>): what is written reads back bit for bit, and a corrupt
// or truncated blob fails as qd::StateError naming what is wrong, never as an allocation or an
// arithmetic overflow sized by a corrupt count.
#include <qd/state_io.hpp>

#include <gtest/gtest.h>

#include <cstdint>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

namespace {

using qd::StateError;
namespace state = qd::state;

std::string error_of(const std::string& bytes, void (*read)(std::istream&)) {
  std::istringstream in(bytes);
  try {
    read(in);
  } catch (const StateError& e) {
    return e.what();
  }
  return "(no error)";
}

template <class T>
std::string raw(const T& v) {
  return std::string(reinterpret_cast<const char*>(&v), sizeof v);
}

TEST(StateIo, VectorsMatricesAndStringsReadBackBitForBit) {
  std::stringstream s;
  const std::vector<double> v = {1.5, -0.0, std::numeric_limits<double>::denorm_min(), 1e300};
  Eigen::MatrixXf m(2, 3);
  m << 1, 2, 3, 4, 5, 6;
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> r(3, 2);
  r << 1, 2, 3, 4, 5, 6;
  const std::string text("with\0nul", 8);
  state::write_vector(s, v);
  state::write_matrix(s, m);
  state::write_matrix(s, r);
  state::write_string(s, text);
  state::write_vector(s, std::vector<int>{});
  // A vector longer than one 16 MiB chunk of the reader.
  std::vector<std::uint8_t> big((std::size_t{1} << 24) + 3);
  for (std::size_t i = 0; i < big.size(); ++i) big[i] = static_cast<std::uint8_t>(i * 7);
  state::write_vector(s, big);

  EXPECT_EQ(state::read_vector<double>(s), v);
  Eigen::MatrixXf m2;
  state::read_matrix(s, m2);
  EXPECT_EQ(m2, m);
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> r2;
  state::read_matrix(s, r2);
  EXPECT_EQ(r2, r);
  EXPECT_EQ(state::read_string(s), text);
  EXPECT_TRUE(state::read_vector<int>(s).empty());
  EXPECT_EQ(state::read_vector<std::uint8_t>(s), big);
  EXPECT_EQ(s.peek(), std::char_traits<char>::eof());
}

TEST(StateIo, ACountTheBlobDoesNotHoldEndsEarlyWithoutAllocatingIt) {
  // 2^36 doubles (512 GiB) claimed, one present.
  const std::string vector_blob = raw(std::uint64_t{1} << 36) + raw(1.0);
  EXPECT_EQ(error_of(vector_blob, [](std::istream& in) { state::read_vector<double>(in); }), "state blob ends early");
  // 2^18 x 2^18 floats (256 GiB) claimed, one present.
  const std::string matrix_blob =
      raw(std::int64_t{1} << 18) + raw(std::int64_t{1} << 18) + raw(std::uint32_t{4}) + raw(1.0f);
  EXPECT_EQ(error_of(matrix_blob,
                     [](std::istream& in) {
                       Eigen::MatrixXf m;
                       state::read_matrix(in, m);
                     }),
            "state blob ends early");
  const std::string string_blob = raw(std::uint64_t{1} << 30) + "abc";
  EXPECT_EQ(error_of(string_blob, [](std::istream& in) { state::read_string(in); }), "state blob ends early");
}

TEST(StateIo, MalformedHeadersAreNamed) {
  auto read_floats = [](std::istream& in) {
    Eigen::MatrixXf m;
    state::read_matrix(in, m);
  };
  const std::uint32_t four = 4;
  // rows x cols overflows 64 bits: refused by division, not by an overflowing product.
  EXPECT_EQ(error_of(raw(std::int64_t{1} << 40) + raw(std::int64_t{1} << 40) + raw(four), read_floats),
            "state blob has a malformed matrix header");
  EXPECT_EQ(error_of(raw(std::int64_t{-1}) + raw(std::int64_t{2}) + raw(four), read_floats),
            "state blob has a malformed matrix header");
  EXPECT_EQ(error_of(raw(std::int64_t{1}) + raw(std::int64_t{1}) + raw(std::uint32_t{8}) + raw(1.0), read_floats),
            "state blob has a malformed matrix header");  // doubles where floats are expected
  EXPECT_EQ(error_of(raw(std::uint64_t{1} << 40), [](std::istream& in) { state::read_vector<double>(in); }),
            "state blob has an implausible vector size");
  EXPECT_EQ(error_of(raw((std::uint64_t{1} << 30) + 1), [](std::istream& in) { state::read_string(in); }),
            "state blob has an implausible string size");
  EXPECT_EQ(error_of("AB", [](std::istream& in) { state::expect_tag(in, "ABCD"); }),
            "state blob ends before block 'ABCD'");
  EXPECT_EQ(error_of("ABCE", [](std::istream& in) { state::expect_tag(in, "ABCD"); }),
            "state blob has block 'ABCE' where 'ABCD' was expected");
}

}  // namespace
