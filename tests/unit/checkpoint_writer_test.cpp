#include "runtime/checkpoint_writer.hpp"
#include "files.hpp"

#include <gtest/gtest.h>

#include <unistd.h>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <future>
#include <memory>
#include <string>

using qd::runtime::CheckpointWriter;
namespace fs = std::filesystem;

namespace {

using qd::test::slurp;

struct FreeBuffer {
  void operator()(char* p) const { std::free(p); }
};

// Writes a checkpoint whose one append is a direct (O_DIRECT) new file of `size` bytes in `dir`,
// from an aligned buffer whose padding holds junk, over an existing longer file; checks that the
// file holds exactly the bytes and that the checkpoint committed.
void expect_direct_append_writes_exact_bytes(const fs::path& dir, bool direct_io) {
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::size_t size = 10000, align = CheckpointWriter::kDirectAlignment;
  const std::size_t padded = (size + align - 1) / align * align;
  std::unique_ptr<char, FreeBuffer> buffer(static_cast<char*>(std::aligned_alloc(align, padded)));
  ASSERT_TRUE(buffer);
  std::string expected(size, '\0');
  for (std::size_t i = 0; i < size; ++i) expected[i] = static_cast<char>('a' + i * 7 % 26);
  std::copy(expected.begin(), expected.end(), buffer.get());
  std::fill(buffer.get() + size, buffer.get() + padded, '#');  // padding: must not reach the file
  const fs::path log = dir / "archive-state-00003.bin";
  std::ofstream(log) << std::string(3 * padded, 'x');  // a stale longer file (an uncommitted generation)

  CheckpointWriter::Job job;
  job.checkpoint = dir / "checkpoint.bin";
  job.state = "state";
  job.appends.resize(1);
  job.appends[0].path = log;
  job.appends[0].more = buffer.get();
  job.appends[0].more_size = size;
  job.appends[0].direct = true;
  {
    CheckpointWriter writer(direct_io);
    writer.submit(job);
    writer.wait();
  }
  EXPECT_EQ(fs::file_size(log), size);
  EXPECT_EQ(slurp(log), expected);
  EXPECT_EQ(slurp(dir / "checkpoint.bin"), "state");
  EXPECT_FALSE(fs::exists(dir / "checkpoint.bin.tmp"));
  fs::remove_all(dir);
}

}  // namespace

TEST(CheckpointWriter, DirectAppendWritesExactlyItsBytes) {
  expect_direct_append_writes_exact_bytes(
      fs::temp_directory_path() / ("qd_checkpoint_writer_test-" + std::to_string(::getpid())), true);
}

TEST(CheckpointWriter, DirectAppendThroughThePageCacheWritesTheSameBytes) {
  // The path taken where the file system refuses O_DIRECT.
  expect_direct_append_writes_exact_bytes(
      fs::temp_directory_path() / ("qd_checkpoint_writer_test-buffered-" + std::to_string(::getpid())), false);
}

TEST(CheckpointWriter, AppendCutsUncommittedBytesAndWritesAtItsOffset) {
  const fs::path dir = fs::temp_directory_path() / ("qd_checkpoint_writer_append-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path log = dir / "dataset.bin";
  std::ofstream(log) << "committed|uncommitted garbage";
  const std::string more = "-more";
  CheckpointWriter::Job job;
  job.checkpoint = dir / "checkpoint.bin";
  job.state = "s";
  job.appends.resize(1);
  job.appends[0].path = log;
  job.appends[0].offset = 10;  // "committed|"
  job.appends[0].bytes = "new";
  job.appends[0].more = more.data();
  job.appends[0].more_size = more.size();
  {
    CheckpointWriter writer;
    writer.submit(job);
    writer.wait();
  }
  EXPECT_EQ(slurp(log), "committed|new-more");
  fs::remove_all(dir);
}

TEST(CheckpointWriter, BusyWhileAJobIsBeingWrittenAndNotAfterWait) {
  const fs::path dir = fs::temp_directory_path() / ("qd_checkpoint_writer_busy-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  std::promise<void> started;
  CheckpointWriter writer;
  EXPECT_FALSE(writer.busy());  // nothing submitted yet
  CheckpointWriter::Job job;
  job.checkpoint = dir / "checkpoint.bin";
  job.state = "s";
  job.prepare = [&] {  // holds the writer inside the job until released
    started.set_value();
    released.wait();
  };
  writer.submit(job);
  started.get_future().wait();
  EXPECT_TRUE(writer.busy());
  EXPECT_FALSE(fs::exists(dir / "checkpoint.bin"));
  release.set_value();
  writer.wait();
  EXPECT_FALSE(writer.busy());
  EXPECT_EQ(slurp(dir / "checkpoint.bin"), "s");
  fs::remove_all(dir);
}
