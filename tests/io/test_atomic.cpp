// Atomic writes: the target holds either the old or the complete new bytes.
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <csignal>

#include "core/error.h"
#include "cube_test_util.h"
#include "io/files/atomic_file.h"

namespace ddhgs::io {
namespace {
namespace fs = std::filesystem;

size_t files_in(const fs::path& dir) {
  return size_t(std::distance(fs::directory_iterator(dir), fs::directory_iterator()));
}

TEST(AtomicFile, WritesAndReplacesWholeFiles) {
  fs::path dir = test::temp_dir("atomic_write");
  write_file_atomically(dir / "a.txt", "first");
  write_file_atomically(dir / "a.txt", "second, longer");
  EXPECT_EQ(read_file(dir / "a.txt"), "second, longer");
  write_parts_atomically(dir / "b.bin", {"head", std::string_view("\0x\0", 3), "tail"});
  EXPECT_EQ(read_file(dir / "b.bin"), std::string("head\0x\0tail", 11));
  EXPECT_EQ(files_in(dir), 2u);  // no temporary left behind
}

TEST(AtomicFile, CreatesMissingFolders) {
  fs::path dir = test::temp_dir("atomic_folders");
  write_file_atomically(dir / "x" / "y" / "z.txt", "deep");
  EXPECT_EQ(read_file(dir / "x" / "y" / "z.txt"), "deep");
}

TEST(AtomicFile, FailedWriteKeepsOldFileAndRemovesTemporary) {
  fs::path dir = test::temp_dir("atomic_fail");
  write_file_atomically(dir / "keep.txt", "old");
  fs::path seen_tmp;
  EXPECT_THROW(write_atomically(dir / "keep.txt",
                                [&](const fs::path& tmp) {
                                  seen_tmp = tmp;
                                  test::write_bytes(tmp, "half");
                                  throw std::runtime_error("interrupted");
                                }),
               std::runtime_error);
  EXPECT_EQ(seen_tmp.parent_path(), dir);
  EXPECT_FALSE(fs::exists(seen_tmp));
  EXPECT_EQ(read_file(dir / "keep.txt"), "old");
  EXPECT_EQ(files_in(dir), 1u);
}

TEST(AtomicFile, IoFailuresBecomeErrorsNamingTheTarget) {
  fs::path dir = test::temp_dir("atomic_io_errors");
  // A stream failure inside the writer maps to core::Error naming the target.
  test::expect_error_naming(
      [&] {
        write_atomically(dir / "stream.bin",
                         [](const fs::path&) { throw std::ios_base::failure("disk full"); });
      },
      "stream.bin", "write failed");
  EXPECT_EQ(files_in(dir), 0u);
  // A folder that cannot exist: its would-be parent is a regular file.
  test::write_bytes(dir / "plain", "x");
  test::expect_error_naming([&] { write_file_atomically(dir / "plain" / "out.txt", "y"); },
                            "out.txt", "cannot create its folder");
  // Devices and folders are never replaced by a rename.
  test::expect_error_naming([&] { write_file_atomically("/dev/null", "x"); }, "/dev/null",
                            "not a regular file");
  fs::create_directories(dir / "folder");
  test::expect_error_naming([&] { write_file_atomically(dir / "folder", "x"); }, "folder",
                            "not a regular file");
  EXPECT_TRUE(fs::is_directory(dir / "folder"));
}

// A real failing write(2): a file size limit makes the kernel refuse bytes
// past 1 KiB (EFBIG), as a full disk refuses them with ENOSPC.
TEST(AtomicFile, FailingWriteBecomesErrorAndLeavesNothing) {
  fs::path dir = test::temp_dir("atomic_efbig");
  rlimit old_limit{};
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &old_limit), 0);
  auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
  rlimit small = old_limit;
  small.rlim_cur = 1024;
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &small), 0);
  std::string big(4096, 'x');
  std::string message;
  try {
    write_file_atomically(dir / "big.bin", big);
  } catch (const core::Error& e) {
    message = e.what();
  }
  setrlimit(RLIMIT_FSIZE, &old_limit);
  std::signal(SIGXFSZ, old_handler);
  EXPECT_NE(message.find("big.bin"), std::string::npos) << message;
  EXPECT_NE(message.find("write failed"), std::string::npos) << message;
  EXPECT_EQ(files_in(dir), 0u);
}

TEST(AtomicFile, ReadFileErrors) {
  fs::path dir = test::temp_dir("atomic_read");
  test::expect_error_naming([&] { read_file(dir / "absent.txt"); }, "absent.txt", "not found");
  test::expect_error_naming([&] { read_file(dir); }, "atomic_read", "folder");
}

}  // namespace
}  // namespace ddhgs::io

namespace ddhgs::io {
namespace {

// /dev/full answers every write with ENOSPC, as a full disk does: the sink
// keeps the failure (it may sit under a C callback that must not throw) and
// finish() reports it naming the target.
TEST(FileSink, FullDiskIsReportedByFinishNamingTheTarget) {
  if (!std::filesystem::exists("/dev/full")) GTEST_SKIP() << "no /dev/full";
  FileSink sink("/dev/full", "run/checkpoint.pt");
  const std::string bytes(4096, 'x');
  EXPECT_EQ(sink.write(bytes.data(), bytes.size()), bytes.size());
  EXPECT_EQ(sink.write(bytes.data(), bytes.size()), bytes.size());
  test::expect_error_naming([&] { sink.finish(); }, "run/checkpoint.pt",
                            "write failed: no space left on device");
}

TEST(FileSink, StreamedWriteReplacesTheFileWhole) {
  const std::filesystem::path dir = test::temp_dir("sink_stream");
  write_stream_atomically(dir / "a.bin", [](FileSink& sink) {
    for (char c : std::string("abc")) sink.write(&c, 1);
  });
  EXPECT_EQ(read_file(dir / "a.bin"), "abc");
  EXPECT_EQ(files_in(dir), 1u);
}

}  // namespace
}  // namespace ddhgs::io
