// io::require_regular_file and the readers built on it: a FIFO, a folder or
// a device is refused by name before anything opens it (opening a FIFO for
// reading waits for a writer for ever).
#include <gtest/gtest.h>
#include <sys/stat.h>

#include "io/cube/cube.h"
#include "io/files/atomic_file.h"
#include "io/files/input_file.h"
#include "support/error_text.h"
#include "support/test_support.h"

namespace ddhgs::io {
namespace {
namespace fs = std::filesystem;

TEST(InputFile, SaysWhatAPathIsWhenItIsNoRegularFile) {
  const fs::path dir = test::temp_dir("input_file");
  write_file_atomically(dir / "a.txt", "a");
  fs::create_symlink(dir / "a.txt", dir / "link.txt");
  EXPECT_EQ(test::error_of([&] { require_regular_file(dir / "a.txt"); }), "(no error)");
  EXPECT_EQ(test::error_of([&] { require_regular_file(dir / "link.txt"); }), "(no error)");
  EXPECT_EQ(test::error_of([&] { require_regular_file(dir / "none"); }),
            (dir / "none").string() + ": file not found");
  EXPECT_EQ(test::error_of([&] { require_regular_file(dir); }),
            dir.string() + ": is a folder, expected a file");
  ASSERT_EQ(::mkfifo((dir / "pipe").c_str(), 0600), 0);
  EXPECT_EQ(test::error_of([&] { require_regular_file(dir / "pipe"); }),
            (dir / "pipe").string() + ": is a FIFO (named pipe), expected a regular file");
  EXPECT_EQ(test::error_of([&] { require_regular_file("/dev/null"); }),
            "/dev/null: is a device, expected a regular file");
}

TEST(InputFile, ReadersRefuseAFifoInsteadOfWaiting) {
  const fs::path dir = test::temp_dir("input_file_readers");
  for (const char* name : {"view.npy", "view.pt", "view.tif", "transforms.json"}) {
    const fs::path fifo = dir / name;
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    const std::string what = test::error_of([&] {
      if (fifo.extension() == ".json")
        read_file(fifo);
      else
        read_cube(fifo);
    });
    EXPECT_EQ(what, fifo.string() + ": is a FIFO (named pipe), expected a regular file");
  }
}

}  // namespace
}  // namespace ddhgs::io
