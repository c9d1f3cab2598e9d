#include "runtime/csv.hpp"
#include "files.hpp"

#include <qd/errors.hpp>

#include <gtest/gtest.h>

#include <unistd.h>
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>

using namespace qd::runtime;
namespace fs = std::filesystem;

namespace {
using qd::test::slurp;

// A fresh directory holding archive.csv = "old\n"; returns the file's path.
fs::path directory_with_old_file(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("qd_csv_test-" + std::to_string(::getpid()) + "-" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  std::ofstream(d / "archive.csv") << "old\n";
  return d / "archive.csv";
}
}  // namespace

TEST(AtomicFile, PiecesAppearTogetherOnlyAtCommit) {
  const fs::path path = directory_with_old_file("commit");
  const fs::path dir = path.parent_path();
  AtomicFile f(path);
  f.write("a,b\n");
  f.write(std::string(3 << 20, 'x'));
  f.write("\nend\n");
  EXPECT_EQ(slurp(path), "old\n");  // readers still see the previous file
  f.commit();
  EXPECT_EQ(slurp(path), "a,b\n" + std::string(3 << 20, 'x') + "\nend\n");
  EXPECT_FALSE(fs::exists(dir / "archive.csv.tmp"));
  fs::remove_all(dir);
}

TEST(AtomicFile, AbandonedWriteLeavesThePreviousFile) {
  const fs::path path = directory_with_old_file("abandon");
  const fs::path dir = path.parent_path();
  {
    AtomicFile f(path);
    f.write("half a file");
  }  // an exception unwound here, say
  EXPECT_EQ(slurp(path), "old\n");
  EXPECT_FALSE(fs::exists(dir / "archive.csv.tmp"));
  fs::remove_all(dir);
}

TEST(AtomicFile, UnwritableDirectoryIsAnError) {
  EXPECT_THROW(AtomicFile("/nonexistent-dir-qd/archive.csv"), qd::Error);
}

TEST(NumberFormat, ShortestRoundTripAfterClearingVectorState) {
  const double values[] = {0.1, -1.0 / 3.0, 6.02214076e23, 5e-324, 0.9999999999999999, -0.0, 1e-7};
  for (double v : values) {
    const std::string before = format_number(v);
    clear_upper_vector_state();
    const std::string after = format_number(v);
    EXPECT_EQ(before, after);
    EXPECT_EQ(std::strtod(after.c_str(), nullptr), v) << after;
  }
  EXPECT_EQ(format_number(0.1), "0.1");
  EXPECT_EQ(format_number(-1.0 / 3.0), "-0.3333333333333333");
}

TEST(AppendLog, RowsReachTheFileOnFlushAndOnDestruction) {
  const fs::path path = directory_with_old_file("append");
  const fs::path dir = path.parent_path();
  {
    AppendLog log(std::chrono::hours(1));
    log.append(path, "a\n");
    log.append(path, "b\n");
    // Buffered: within the flush interval nothing is written yet (the old content stays).
    EXPECT_EQ(slurp(path), "old\n");
    log.flush();
    EXPECT_EQ(slurp(path), "old\na\nb\n");
    log.flush();  // nothing pending: no change
    log.append(path, "c\n");
  }
  EXPECT_EQ(slurp(path), "old\na\nb\nc\n");
  fs::remove_all(dir);
}

TEST(AppendLog, ZeroIntervalWritesEveryAppend) {
  const fs::path path = directory_with_old_file("append-zero");
  AppendLog log(std::chrono::seconds(0));
  log.append(path, "a\n");
  EXPECT_EQ(slurp(path), "old\na\n");
  log.append(path, "b\n");
  EXPECT_EQ(slurp(path), "old\na\nb\n");
  fs::remove_all(path.parent_path());
}

TEST(AppendLog, AppendToFileWritesAtOnce) {
  const fs::path path = directory_with_old_file("append-once");
  append_to_file(path, "row\n");
  EXPECT_EQ(slurp(path), "old\nrow\n");
  fs::remove_all(path.parent_path());
}

namespace {
// Piece b of the test text: its number repeated (b % 7 + 1) * 1000 times, so pieces differ in
// length and in how long they take.
char* format_piece(std::size_t b, char* out) {
  const std::string text = std::to_string(b) + ';';
  for (std::size_t i = 0; i < (b % 7 + 1) * 1000; ++i) out = std::copy(text.begin(), text.end(), out);
  return out;
}
constexpr std::size_t kPieceBytes = 7 * 1000 * 8;
}  // namespace

TEST(FormatInOrder, PiecesFromManyThreadsArriveInOrder) {
  std::string expected;
  std::string buf(kPieceBytes, '\0');
  for (std::size_t b = 0; b < 200; ++b) expected.append(buf.data(), format_piece(b, buf.data()));
  for (unsigned threads : {1u, 2u, 5u}) {
    std::string got;
    std::size_t writes = 0;
    format_in_order(200, kPieceBytes, threads, format_piece, [&](const char* text, std::size_t size) {
      got.append(text, size);
      ++writes;
    });
    EXPECT_EQ(writes, 200u) << threads << " threads";
    EXPECT_TRUE(got == expected) << threads << " threads";
  }
}

TEST(FormatInOrder, NoPiecesNoWrites) {
  bool wrote = false;
  format_in_order(0, 16, 4, format_piece, [&](const char*, std::size_t) { wrote = true; });
  EXPECT_FALSE(wrote);
}

TEST(FormatInOrder, FormatErrorStopsTheWorkAndReachesTheCaller) {
  std::string got, expected;
  std::string buf(kPieceBytes, '\0');
  for (std::size_t b = 0; b < 30; ++b) expected.append(buf.data(), format_piece(b, buf.data()));
  auto failing = [](std::size_t b, char* out) -> char* {
    if (b == 30) throw std::runtime_error("piece 30 failed");
    return format_piece(b, out);
  };
  try {
    format_in_order(100, kPieceBytes, 3, failing, [&](const char* text, std::size_t size) { got.append(text, size); });
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "piece 30 failed");
  }
  // What was written is an in-order prefix that never reaches the failed piece.
  EXPECT_LE(got.size(), expected.size());
  EXPECT_EQ(got, expected.substr(0, got.size()));
}

TEST(FormatInOrder, WriteErrorReachesTheCaller) {
  std::size_t writes = 0;
  auto failing_write = [&](const char*, std::size_t) {
    if (++writes == 3) throw qd::Error("disk full");
  };
  EXPECT_THROW(format_in_order(50, kPieceBytes, 4, format_piece, failing_write), qd::Error);
  EXPECT_EQ(writes, 3u);
}
