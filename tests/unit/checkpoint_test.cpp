// The checkpoint's checksum: CRC-32C against its published check value and against Boost's
// table-driven implementation for every length and alignment (the fast path reads 8 bytes at a time).
#include "runtime/checkpoint.hpp"

#include <gtest/gtest.h>
#include <boost/crc.hpp>

#include <cstdint>
#include <string>

namespace {
std::uint32_t reference_crc32c(const char* bytes, std::size_t size) {
  boost::crc_optimal<32, 0x1EDC6F41, 0xFFFFFFFF, 0xFFFFFFFF, true, true> crc;
  crc.process_bytes(bytes, size);
  return crc.checksum();
}
}  // namespace

TEST(Crc32c, CheckValue) {
  EXPECT_EQ(qd::runtime::crc32c("123456789", 9), 0xE3069283u);  // the catalogue's check value
  EXPECT_EQ(qd::runtime::crc32c("", 0), 0u);
}

TEST(Crc32c, MatchesTableDrivenCrcForEveryLengthAndOffset) {
  std::string bytes(300, '\0');
  for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<char>((i * 131 + 7) & 0xFF);
  for (std::size_t offset = 0; offset < 8; ++offset)
    for (std::size_t size = 0; size + offset <= bytes.size(); size += 7)
      ASSERT_EQ(qd::runtime::crc32c(bytes.data() + offset, size), reference_crc32c(bytes.data() + offset, size))
          << "offset " << offset << " size " << size;
}

TEST(Crc32c, OneFlippedBitChangesIt) {
  std::string bytes(4096, 'x');
  const std::uint32_t before = qd::runtime::crc32c(bytes.data(), bytes.size());
  bytes[2049] = static_cast<char>(bytes[2049] ^ 0x10);
  EXPECT_NE(qd::runtime::crc32c(bytes.data(), bytes.size()), before);
}

// A log's checksum is extended chunk by chunk as it grows (RunDirectory::log_sizes).
TEST(Crc32c, ExtendingEqualsTheWhole) {
  const std::string text = "loop,iteration,evaluations\n0,0,100\n1,0,120\n1,1,140\n";
  for (std::size_t cut = 0; cut <= text.size(); ++cut) {
    const std::uint32_t head = qd::runtime::crc32c(text.data(), cut);
    EXPECT_EQ(qd::runtime::crc32c(text.data() + cut, text.size() - cut, head),
              qd::runtime::crc32c(text.data(), text.size()))
        << cut;
  }
}
