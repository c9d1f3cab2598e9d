#include "runtime/run_files.hpp"
#include "files.hpp"
#include "runtime/number_text.hpp"

#include <qd/errors.hpp>

#include <gtest/gtest.h>

#include <fcntl.h>
#include <linux/fs.h>
#include <sys/ioctl.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
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
  const fs::path d = fs::temp_directory_path() / ("qd_run_files_test-" + std::to_string(::getpid()) + "-" + name);
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

TEST(AppendLog, AFailedWriteIsASystemErrorNamingTheFile) {
  const fs::path path = directory_with_old_file("full");
  AppendLog log(path);
  try {
    const qd::test::FileSizeLimit full_disk(fs::file_size(path) + 2);
    log.append("a row longer than the space left\n");
    FAIL() << "no error";
  } catch (const qd::SystemError& e) {
    EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
  }
  fs::remove_all(path.parent_path());
}

TEST(AppendLog, AppendToFileWritesAtOnce) {
  const fs::path path = directory_with_old_file("append-once");
  append_to_file(path, "row\n");
  EXPECT_EQ(slurp(path), "old\nrow\n");
  fs::remove_all(path.parent_path());
}

// Issue 32: a run directory's files are regular files of its own, never written through a symlink,
// never shared with another directory, never read without end.
namespace {
fs::path fresh_directory(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("qd_run_files_test-" + std::to_string(::getpid()) + "-" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}
std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(AtomicFile, NeverWritesThroughASymlinkLeftAsItsTemporaryFile) {
  const fs::path d = fresh_directory("planted");
  std::ofstream(d / "victim") << "victim\n";
  fs::create_symlink(d / "victim", d / "status.tmp");
  write_file_atomic(d / "status", "running\n");
  EXPECT_EQ(slurp(d / "victim"), "victim\n");
  EXPECT_EQ(slurp(d / "status"), "running\n");
  fs::remove_all(d);
}

TEST(RunFiles, OpenForUpdateRefusesWhatIsNotARegularFile) {
  const fs::path d = fresh_directory("kinds");
  std::ofstream(d / "other.csv") << "x\n";
  fs::create_symlink(d / "other.csv", d / "link.csv");
  ASSERT_EQ(::mkfifo((d / "fifo.csv").c_str(), 0644), 0);
  fs::create_directory(d / "dir.csv");
  EXPECT_NE(
      error_of([&] { open_for_update(d / "link.csv", O_APPEND, true); }).find("is a symbolic link, not a regular"),
      std::string::npos);
  EXPECT_NE(error_of([&] { open_for_update(d / "fifo.csv", O_APPEND, true); }).find("is a FIFO, not a regular file"),
            std::string::npos);
  EXPECT_NE(error_of([&] { open_for_update(d / "dir.csv", O_APPEND, true); }).find("is a directory"),
            std::string::npos);
  EXPECT_EQ(slurp(d / "other.csv"), "x\n");
  fs::remove_all(d);
}

TEST(RunFiles, AHardLinkedLogIsMadePrivateBeforeItChanges) {
  const fs::path d = fresh_directory("hardlink");
  fs::create_directories(d / "copy");
  std::ofstream(d / "metrics.csv") << "header\nrow 1\n";
  fs::create_hard_link(d / "metrics.csv", d / "copy" / "metrics.csv");  // cp -al
  AppendLog log(d / "copy" / "metrics.csv");
  log.append("row 2 of the copy\n");
  EXPECT_EQ(slurp(d / "metrics.csv"), "header\nrow 1\n");
  EXPECT_EQ(slurp(d / "copy" / "metrics.csv"), "header\nrow 1\nrow 2 of the copy\n");
  EXPECT_EQ(fs::hard_link_count(d / "metrics.csv"), 1u);
  // A link made while the log is open is broken before the next row.
  fs::create_hard_link(d / "copy" / "metrics.csv", d / "late.csv");
  log.append("row 3\n");
  EXPECT_EQ(slurp(d / "late.csv"), "header\nrow 1\nrow 2 of the copy\n");
  EXPECT_EQ(slurp(d / "copy" / "metrics.csv"), "header\nrow 1\nrow 2 of the copy\nrow 3\n");
  fs::remove_all(d);
}

TEST(RunFiles, ReadingRefusesFifosAndDevicesAtOnceAndBoundsTheSize) {
  const fs::path d = fresh_directory("read");
  ASSERT_EQ(::mkfifo((d / "checkpoint.bin").c_str(), 0644), 0);  // no writer: a plain open would block
  EXPECT_NE(error_of([&] { read_run_file(d / "checkpoint.bin", 100); }).find("is a FIFO, not a regular file"),
            std::string::npos);
  fs::create_symlink("/dev/zero", d / "dataset.bin");
  EXPECT_NE(error_of([&] { read_run_file_prefix(d / "dataset.bin", 100); }).find("is a symbolic link"),
            std::string::npos);
  std::ofstream(d / "status") << std::string(200, 'x');
  EXPECT_NE(error_of([&] { read_run_file(d / "status", 100); }).find("larger (200 bytes) than its format allows (100)"),
            std::string::npos);
  EXPECT_NE(error_of([&] { read_run_file_prefix(d / "status", 300); }).find("is shorter than the checkpoint records"),
            std::string::npos);
  EXPECT_EQ(read_run_file_prefix(d / "status", 10), std::string(10, 'x'));
  EXPECT_NE(error_of([&] { read_run_file(d / "missing", 100); }).find("is missing"), std::string::npos);
  fs::remove_all(d);
}

// What a rename would destroy or cannot replace is refused before anything is written: a device
// or FIFO named as an output (--traces /dev/null, as root, became a regular file), a directory in
// place of the file or of its temporary file. A symlink is replaced, never written through.
TEST(AtomicFile, NeverReplacesADeviceFifoOrDirectory) {
  const fs::path d = fresh_directory("replace");
  ASSERT_EQ(::mkfifo((d / "fifo.csv").c_str(), 0644), 0);
  fs::create_directory(d / "dir.csv");
  fs::create_directory(d / "status.tmp");
  EXPECT_NE(error_of([&] { write_file_atomic(d / "fifo.csv", "x\n"); }).find("fifo.csv is a FIFO, not a regular file"),
            std::string::npos);
  EXPECT_NE(error_of([&] { write_file_atomic(d / "dir.csv", "x\n"); }).find("dir.csv is a directory"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              write_file_atomic(d / "status", "x\n");
            }).find("status.tmp is a directory, where qdrun writes its temporary file for status"),
            std::string::npos);
  EXPECT_TRUE(fs::is_fifo(d / "fifo.csv"));
  EXPECT_FALSE(fs::exists(d / "fifo.csv.tmp"));
  EXPECT_FALSE(fs::exists(d / "status"));
  std::ofstream(d / "target") << "target\n";
  fs::create_symlink(d / "target", d / "link.csv");
  write_file_atomic(d / "link.csv", "new\n");
  EXPECT_EQ(slurp(d / "target"), "target\n");
  EXPECT_FALSE(fs::is_symlink(d / "link.csv"));
  EXPECT_EQ(slurp(d / "link.csv"), "new\n");
  if (::geteuid() == 0 && ::mknod((d / "null").c_str(), S_IFCHR | 0666, makedev(1, 3)) == 0) {
    EXPECT_NE(error_of([&] { write_file_atomic(d / "null", "x\n"); }).find("null is a character device"),
              std::string::npos);
    EXPECT_TRUE(fs::is_character_file(d / "null"));
  }
  fs::remove_all(d);
}

namespace {
// Sets or clears the immutable attribute (chattr +i) of `path`; false where that is not allowed
// (not root, a file system without it).
bool set_immutable(const fs::path& path, bool on) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;
  int flags = 0;
  bool ok = ::ioctl(fd, FS_IOC_GETFLAGS, &flags) == 0;
  flags = on ? (flags | FS_IMMUTABLE_FL) : (flags & ~FS_IMMUTABLE_FL);
  ok = ok && ::ioctl(fd, FS_IOC_SETFLAGS, &flags) == 0;
  ::close(fd);
  return ok;
}
}  // namespace

// A rename the system refuses (an immutable file in the way) is an error, and the temporary file
// is not left behind.
TEST(AtomicFile, AFailedRenameLeavesNoTemporaryFile) {
  const fs::path d = fresh_directory("rename");
  std::ofstream(d / "status") << "old\n";
  if (!set_immutable(d / "status", true)) {
    fs::remove_all(d);
    GTEST_SKIP() << "cannot make a file immutable here";
  }
  const std::string error = error_of([&] { write_file_atomic(d / "status", "new\n"); });
  set_immutable(d / "status", false);
  EXPECT_NE(error.find("cannot rename"), std::string::npos) << error;
  EXPECT_FALSE(fs::exists(d / "status.tmp"));
  EXPECT_EQ(slurp(d / "status"), "old\n");
  fs::remove_all(d);
}
