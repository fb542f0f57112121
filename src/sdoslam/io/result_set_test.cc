#include "sdoslam/io/result_set.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "sdoslam/core/error.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

using ::testing::HasSubstr;
using testing::MessageOf;
using testing::ReadText;
using testing::TempDir;
using testing::WriteText;
namespace fs = std::filesystem;

int CountStaging(const fs::path& out) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(out))
    n += e.path().filename().string().rfind(".sdoslam-staging-", 0) == 0;
  return n;
}

TEST(Sha256, MatchesTheStandardTestVector) {
  TempDir dir;
  WriteText(dir / "abc", "abc");  // FIPS 180-2, appendix B.1
  EXPECT_EQ(Sha256OfFile(dir / "abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
}

TEST(ResultSet, CommitPutsEveryFileInPlaceWithAManifestThatVerifies) {
  TempDir dir;
  const fs::path out = dir / "out";
  {
    ResultSetWriter writer(out);
    writer.WriteText("CameraTrajectory.txt", "1 0 0 0 0 0 0 1\n");
    writer.WriteText("masks/0001.png", "mask");
    // Nothing reaches the output folder before the commit.
    EXPECT_FALSE(fs::exists(out / "CameraTrajectory.txt"));
    const ResultManifest m = writer.Commit("complete", {{"frames", 1}});
    EXPECT_EQ(m.files.size(), 2u);
  }
  EXPECT_EQ(ReadText(out / "CameraTrajectory.txt"), "1 0 0 0 0 0 0 1\n");
  EXPECT_EQ(ReadText(out / "masks/0001.png"), "mask");
  EXPECT_EQ(CountStaging(out), 0);
  const ResultManifest m = VerifyResultSet(out);
  EXPECT_EQ(m.status, "complete");
  EXPECT_EQ(m.info.at("frames").get<int>(), 1);
  ASSERT_NE(m.Find("masks/0001.png"), nullptr);
  EXPECT_EQ(m.Find("masks/0001.png")->size, 4u);
}

TEST(ResultSet, ARerunReplacesTheOldSetAsAWholeStaleFilesIncluded) {
  TempDir dir;
  const fs::path out = dir / "out";
  {
    ResultSetWriter writer(out);
    writer.WriteText("frames.csv", "old");
    writer.WriteText("masks/0001.png", "old mask 1");
    writer.WriteText("masks/0002.png", "old mask 2");
    writer.WriteText("overlays/0001.png", "old overlay");
    writer.Commit("complete", {});
  }
  WriteText(out / "notes.txt", "the user's own file");
  {
    ResultSetWriter writer(out);
    writer.WriteText("frames.csv", "new");
    writer.WriteText("masks/0001.png", "new mask 1");
    writer.Commit("interrupted", {});
  }
  EXPECT_EQ(ReadText(out / "frames.csv"), "new");
  EXPECT_EQ(ReadText(out / "masks/0001.png"), "new mask 1");
  EXPECT_FALSE(fs::exists(out / "masks/0002.png"));
  EXPECT_FALSE(fs::exists(out / "overlays"));
  EXPECT_EQ(ReadText(out / "notes.txt"), "the user's own file");
  EXPECT_EQ(VerifyResultSet(out).status, "interrupted");
}

TEST(ResultSet, ResultsOfAnOlderVersionWithoutManifestAreReplacedToo) {
  TempDir dir;
  const fs::path out = dir / "out";
  WriteText(out / "features.csv", "stale");
  WriteText(out / "masks/0009.png", "stale");
  {
    ResultSetWriter writer(out);
    writer.WriteText("frames.csv", "new");
    writer.Commit("complete", {});
  }
  EXPECT_FALSE(fs::exists(out / "features.csv"));
  EXPECT_FALSE(fs::exists(out / "masks"));
}

TEST(ResultSet, WithoutCommitTheOldSetStaysUntouchedAndNoStagingIsLeft) {
  TempDir dir;
  const fs::path out = dir / "out";
  {
    ResultSetWriter writer(out);
    writer.WriteText("frames.csv", "old");
    writer.Commit("complete", {});
  }
  {
    ResultSetWriter writer(out);
    writer.WriteText("frames.csv", "half of a new run");
  }  // an error ended the run
  EXPECT_EQ(ReadText(out / "frames.csv"), "old");
  EXPECT_EQ(CountStaging(out), 0);
  EXPECT_NO_THROW(VerifyResultSet(out));
}

TEST(ResultSet, AFailedRunLeavesNoFolderItCreated) {
  TempDir dir;
  { ResultSetWriter writer(dir / "new" / "out"); }
  EXPECT_FALSE(fs::exists(dir / "new" / "out"));
}

TEST(ResultSet, AStagingFolderOfACutOffRunIsRefusedByReadersAndRemovedByTheNextRun) {
  TempDir dir;
  const fs::path out = dir / "out";
  WriteText(out / ".sdoslam-staging-99999/frames.csv", "cut off");
  WriteText(out / "CameraTrajectory.txt", "1 0 0 0 0 0 0 1\n");
  EXPECT_THAT(MessageOf([&] { VerifyResultSet(out); }), HasSubstr("cut off"));
  EXPECT_THAT(MessageOf([&] { VerifyResultFile(out / "CameraTrajectory.txt"); }),
              HasSubstr("cut off"));
  {
    ResultSetWriter writer(out);
    EXPECT_EQ(CountStaging(out), 1);  // its own
  }
  EXPECT_EQ(CountStaging(out), 0);
}

TEST(ResultSet, AFileChangedAfterTheCommitIsRefusedNamingIt) {
  TempDir dir;
  const fs::path out = dir / "out";
  {
    ResultSetWriter writer(out);
    writer.WriteText("CameraTrajectory.txt", "1 0 0 0 0 0 0 1\n");
    writer.WriteText("frames.csv", "index\n");
    writer.Commit("complete", {});
  }
  EXPECT_TRUE(VerifyResultFile(out / "CameraTrajectory.txt").has_value());
  WriteText(out / "CameraTrajectory.txt", "2 0 0 0 0 0 0 1\n");  // same size, other content
  EXPECT_THAT(MessageOf([&] { VerifyResultSet(out); }), HasSubstr("CameraTrajectory.txt: differs"));
  EXPECT_THAT(MessageOf([&] { VerifyResultFile(out / "CameraTrajectory.txt"); }),
              HasSubstr("differs"));
  fs::remove(out / "frames.csv");
  WriteText(out / "CameraTrajectory.txt", "1 0 0 0 0 0 0 1\n");
  EXPECT_THAT(MessageOf([&] { VerifyResultSet(out); }), HasSubstr("frames.csv: missing"));
}

TEST(ResultSet, FilesFromElsewhereAndFoldersWithoutManifestAreToldApart) {
  TempDir dir;
  WriteText(dir / "other_tool.txt", "1 0 0 0 0 0 0 1\n");
  EXPECT_FALSE(VerifyResultFile(dir / "other_tool.txt").has_value());
  EXPECT_THAT(MessageOf([&] { VerifyResultSet(dir.path()); }), HasSubstr("no manifest.json"));
  WriteText(dir / "manifest.json", "{\"format\": \"something else\"}");
  EXPECT_THAT(MessageOf([&] { VerifyResultSet(dir.path()); }), HasSubstr("manifest"));
}

TEST(ResultSet, AnUnwritableOutputFolderFailsAtOnceAsAnIoError) {
  TempDir dir;
  WriteText(dir / "a_file", "x");
  EXPECT_THROW(ResultSetWriter(dir / "a_file"), IoError);
  // A folder nobody may create files in, root included: /proc/self.
  try {
    ResultSetWriter writer("/proc/self");
    FAIL() << "no error";
  } catch (const IoError& e) {
    EXPECT_THAT(e.what(), HasSubstr("cannot write into the output folder /proc/self"));
  }
  EXPECT_THROW(ResultSetWriter("/proc/self/no/such/folder"), IoError);
}

TEST(ResultSet, ASecondWriterOnTheSameFolderIsRefused) {
  TempDir dir;
  ResultSetWriter first(dir / "out");
  EXPECT_THAT(MessageOf([&] { ResultSetWriter second(dir / "out"); }),
              HasSubstr("another sdoslam run"));
}

}  // namespace
}  // namespace sdoslam
