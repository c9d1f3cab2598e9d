// The representation's training logs (qd::TrainingLog): the core owns the files. A log name is a
// plain .csv file name that is none of the run's own; the header is written once; a file no
// checkpoint vouches for starts again; a failed write is a system error naming the log; a symlink in
// its place is refused and a log shared with another directory is made private first.
#include "files.hpp"
#include "runtime/run_directory.hpp"

#include <qd/errors.hpp>

#include <gtest/gtest.h>

#include <unistd.h>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace fs = std::filesystem;
using qd::runtime::is_training_log_name;
using qd::runtime::RunDirectory;

namespace {
std::string read(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}
fs::path fresh_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("qd_training_log_test-" + std::to_string(::getpid()) + "-" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}
}  // namespace

TEST(TrainingLog, NamesArePlainCsvFilesOtherThanTheRunsOwn) {
  for (const char* ok : {"losses.csv", "pca.csv", "my_model-2.csv", "a.b.csv"})
    EXPECT_TRUE(is_training_log_name(ok)) << ok;
  for (const char* bad :
       {"", ".csv", ".hidden.csv", "losses.txt", "losses", "../x.csv", "sub/x.csv", "/tmp/x.csv", "a b.csv",
        "metrics.csv", "training.csv", "archive.csv", "centroids.csv", "fault-offspring.csv"})
    EXPECT_FALSE(is_training_log_name(bad)) << bad;
}

TEST(TrainingLog, HeaderOnceRowsAppendedAndAnUnvouchedFileStartsAgain) {
  const fs::path d = fresh_dir("append");
  RunDirectory dir(d);
  dir.append_log("losses.csv", "loop,epoch\n", "", false);  // the header even before any row
  EXPECT_EQ(read(d / "losses.csv"), "loop,epoch\n");
  dir.append_log("losses.csv", "loop,epoch\n", "0,0\n", false);
  dir.append_log("losses.csv", "loop,epoch\n", "0,1\n", false);
  EXPECT_EQ(read(d / "losses.csv"), "loop,epoch\n0,0\n0,1\n");
  // What a session that stopped before its next checkpoint left: discarded when the log restarts.
  dir.append_log("losses.csv", "loop,epoch\n", "1,0\n", true);
  EXPECT_EQ(read(d / "losses.csv"), "loop,epoch\n1,0\n");
  fs::remove_all(d);
}

// A log that cannot be written fails the run (a system error naming the file), never a silent gap.
TEST(TrainingLog, AFailedWriteIsASystemErrorNamingTheLog) {
  const fs::path d = fresh_dir("full");
  RunDirectory dir(d);
  dir.append_log("losses.csv", "loop,epoch\n", "0,0\n", false);
  try {
    const qd::test::FileSizeLimit full_disk(fs::file_size(d / "losses.csv") + 2);
    dir.append_log("losses.csv", "loop,epoch\n", "0,1\n0,2\n", false);
    FAIL() << "no error";
  } catch (const qd::SystemError& e) {
    EXPECT_NE(std::string(e.what()).find("losses.csv"), std::string::npos) << e.what();
  }
  fs::remove_all(d);
}

// Like every file the run changes: never written through a symlink (refused, naming it, the target
// untouched), and a log shared with another directory (cp -al) gets its own copy before it grows.
TEST(TrainingLog, NeverWritesThroughASymlinkOrIntoASharedFile) {
  const fs::path d = fresh_dir("links");
  std::ofstream(d / "elsewhere.csv") << "someone else's file\n";
  fs::create_directories(d / "run");
  fs::create_symlink(d / "elsewhere.csv", d / "run" / "losses.csv");
  RunDirectory dir(d / "run");
  try {
    dir.append_log("losses.csv", "loop,epoch\n", "0,0\n", false);
    FAIL() << "no error";
  } catch (const qd::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("losses.csv is a symbolic link"), std::string::npos) << e.what();
  }
  EXPECT_EQ(read(d / "elsewhere.csv"), "someone else's file\n");

  fs::remove(d / "run" / "losses.csv");
  dir.append_log("losses.csv", "loop,epoch\n", "0,0\n", false);
  fs::create_directories(d / "copy");
  fs::create_hard_link(d / "run" / "losses.csv", d / "copy" / "losses.csv");
  dir.append_log("losses.csv", "loop,epoch\n", "0,1\n", false);
  EXPECT_EQ(read(d / "copy" / "losses.csv"), "loop,epoch\n0,0\n");
  EXPECT_EQ(read(d / "run" / "losses.csv"), "loop,epoch\n0,0\n0,1\n");
  fs::remove_all(d);
}
