#include "runtime/csv.hpp"
#include "files.hpp"

#include <qd/errors.hpp>

#include <gtest/gtest.h>

#include <unistd.h>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
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

TEST(NumberFormat, ShortestRoundTrip) {
  const double values[] = {0.1, -1.0 / 3.0, 6.02214076e23, 5e-324, 0.9999999999999999, -0.0, 1e-7, 1e300};
  for (double v : values) {
    const std::string text = format_number(v);
    EXPECT_EQ(std::strtod(text.c_str(), nullptr), v) << text;
  }
  EXPECT_EQ(format_number(0.1), "0.1");
  EXPECT_EQ(format_number(-1.0 / 3.0), "-0.3333333333333333");
  EXPECT_EQ(format_number(std::nan("")), "nan");
  EXPECT_EQ(format_number(-std::numeric_limits<double>::infinity()), "-inf");
}

TEST(AppendLog, EveryAppendReachesTheFile) {
  const fs::path path = directory_with_old_file("append");
  {
    AppendLog log(path);
    log.append("a\n");
    EXPECT_EQ(slurp(path), "old\na\n");
    log.append("b\n");
    EXPECT_EQ(slurp(path), "old\na\nb\n");
  }
  fs::remove_all(path.parent_path());
}

TEST(AppendLog, AFailedWriteThrows) {
  if (!fs::exists("/dev/full")) GTEST_SKIP() << "no /dev/full";
  AppendLog log("/dev/full");
  EXPECT_THROW(log.append("row\n"), qd::Error);
}

TEST(AppendLog, AppendToFileWritesAtOnce) {
  const fs::path path = directory_with_old_file("append-once");
  append_to_file(path, "row\n");
  EXPECT_EQ(slurp(path), "old\nrow\n");
  fs::remove_all(path.parent_path());
}
