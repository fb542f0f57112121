#include "sdoslam/core/regular_file.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>

#include "sdoslam/core/error.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

TEST(RegularFile, ReadsAWholeFileAndItsHead) {
  testing::TempDir dir;
  testing::WriteText(dir / "a.txt", "0123456789");
  EXPECT_EQ(ReadRegularFile(dir / "a.txt"), "0123456789");
  EXPECT_EQ(ReadRegularFileIfExists(dir / "a.txt"), "0123456789");
  EXPECT_EQ(ReadRegularFileHead(dir / "a.txt", 4), "0123");
  EXPECT_EQ(ReadRegularFileHead(dir / "a.txt", 100), "0123456789");  // a shorter file: all of it
  EXPECT_NO_THROW(RejectNonRegularFile(dir / "a.txt"));
  // Through a symbolic link: the file it names.
  std::filesystem::create_symlink(dir / "a.txt", dir / "link.txt");
  EXPECT_EQ(ReadRegularFile(dir / "link.txt"), "0123456789");
}

TEST(RegularFile, AMissingFileIsTheCallersToName) {
  testing::TempDir dir;
  EXPECT_FALSE(ReadRegularFileIfExists(dir / "absent.txt"));
  EXPECT_FALSE(ReadRegularFileHead(dir / "absent.txt", 4));
  EXPECT_NO_THROW(RejectNonRegularFile(dir / "absent.txt"));
  EXPECT_EQ(testing::MessageOf([&] { ReadRegularFile(dir / "absent.txt"); }),
            (dir / "absent.txt").string() + ": not found");
}

// A FIFO blocked the reader until someone wrote to it; /dev/zero grew it to 4 GB; a folder read
// as an unnamed error. Each fails at once, naming the path. (/dev/zero is only opened for
// reading: harmless.)
TEST(RegularFile, FoldersFifosAndDevicesAreRefusedAtOnce) {
  testing::TempDir dir;
  const std::filesystem::path fifo = dir / "fifo.txt";
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  std::filesystem::create_directories(dir / "folder");
  for (const std::filesystem::path& path :
       {fifo, dir / "folder", std::filesystem::path("/dev/zero")}) {
    const std::string expected = path.string() + ": not a regular file";
    EXPECT_EQ(testing::MessageOf([&] { ReadRegularFile(path); }), expected);
    EXPECT_EQ(testing::MessageOf([&] { ReadRegularFileIfExists(path); }), expected);
    EXPECT_EQ(testing::MessageOf([&] { ReadRegularFileHead(path, 8); }), expected);
    EXPECT_EQ(testing::MessageOf([&] { RejectNonRegularFile(path); }), expected);
  }
}

TEST(RegularFile, AFileLargerThanTheLimitIsRefusedWithItsSize) {
  testing::TempDir dir;
  testing::WriteText(dir / "big.txt", std::string(2000, 'x'));
  const std::string message =
      testing::MessageOf([&] { ReadRegularFile(dir / "big.txt", /*max_bytes=*/1000); });
  EXPECT_NE(message.find((dir / "big.txt").string() + ": 2000 bytes"), std::string::npos)
      << message;
  EXPECT_EQ(ReadRegularFile(dir / "big.txt", 2000).size(), 2000u);  // the limit itself is fine
  // The head of a large file is read without the rest.
  EXPECT_EQ(ReadRegularFileHead(dir / "big.txt", 3), "xxx");
}

}  // namespace
}  // namespace sdoslam
