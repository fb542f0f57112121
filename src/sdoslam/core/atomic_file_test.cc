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

}  // namespace
}  // namespace sdoslam
