#include "sdoslam/core/atomic_file.h"

#include <gtest/gtest.h>

#include "sdoslam/core/error.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

TEST(AtomicFile, WritesAndCreatesParents) {
  testing::TempDir dir;
  const auto path = dir / "a/b/result.txt";
  WriteFileAtomically(path, [](std::ostream& out) { out << "hello"; });
  EXPECT_EQ(testing::ReadText(path), "hello");
}

TEST(AtomicFile, FailedWriteKeepsTheEarlierResultAndLeavesNoTemporary) {
  testing::TempDir dir;
  const auto path = dir / "result.txt";
  testing::WriteText(path, "earlier result");
  EXPECT_THROW(WriteFileAtomically(path,
                                   [](std::ostream& out) {
                                     out << "half";
                                     throw Error("writer failed midway");
                                   }),
               Error);
  EXPECT_EQ(testing::ReadText(path), "earlier result");
  int files = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(dir.path())) {
    ++files;
  }
  EXPECT_EQ(files, 1);
}

TEST(AtomicFile, PathWriterKeepsExtensionAndReportsFailure) {
  testing::TempDir dir;
  const auto path = dir / "plot.png";
  std::filesystem::path seen;
  WriteFileAtomically(path, [&](const std::filesystem::path& tmp) {
    seen = tmp;
    testing::WriteText(tmp, "png");
    return true;
  });
  EXPECT_EQ(seen.extension(), ".png");
  EXPECT_EQ(testing::ReadText(path), "png");
  EXPECT_THROW(
      WriteFileAtomically(dir / "x.png", [](const std::filesystem::path&) { return false; }),
      Error);
  EXPECT_FALSE(std::filesystem::exists(dir / "x.png"));
}

TEST(AtomicFile, AFailedRenameIsAnIoErrorWithTheRenamesOwnReason) {
  testing::TempDir dir;
  // A non-empty folder where the file should go: the rename fails (EISDIR).
  testing::WriteText(dir / "result.txt" / "inside", "x");
  try {
    WriteFileAtomically(dir / "result.txt", [](std::ostream& o) { o << "new"; });
    FAIL() << "no error";
  } catch (const IoError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("result.txt"), std::string::npos) << message;
    // The clean-up's error code (success) once replaced the rename's in the message.
    EXPECT_EQ(message.find("Success"), std::string::npos) << message;
    EXPECT_NE(message.find(std::make_error_code(std::errc::is_a_directory).message()),
              std::string::npos)
        << message;
  }
}

}  // namespace
}  // namespace sdoslam
