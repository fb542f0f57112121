#include "sdoslam/io/result_set.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <map>

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

// Writes `files` (path in the set -> content) as a result set in `out` and commits it complete;
// with kill_at_step, the process kills itself at that step of the commit (the crash tests).
void CommitSet(const fs::path& out, const std::map<std::string, std::string>& files,
               int kill_at_step = 0) {
  ResultSetWriter writer(out);
  for (const auto& [path, content] : files) writer.WriteText(path, content);
  writer.SetStepHookForTesting([kill_at_step](int step) {
    if (step == kill_at_step) ::raise(SIGKILL);
  });
  writer.Commit("complete", {});
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
  CommitSet(out, {{"frames.csv", "old"},
                  {"masks/0001.png", "old mask 1"},
                  {"masks/0002.png", "old mask 2"},
                  {"overlays/0001.png", "old overlay"}});
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

TEST(ResultSet, FilesItDidNotWriteAreNeverReplacedOrRemoved) {
  TempDir dir;
  const fs::path out = dir / "out";
  // No manifest: a folder of the user's (or of a version before manifests), not a result set.
  WriteText(out / "features.csv", "the user's");
  WriteText(out / "masks/0009.png", "the user's");
  WriteText(out / "frames.csv", "the user's own frames.csv");
  {
    ResultSetWriter writer(out);
    writer.WriteText("frames.csv", "new");
    EXPECT_THAT(MessageOf([&] { writer.Commit("complete", {}); }),
                HasSubstr("frames.csv is in the way: sdoslam did not write it"));
  }
  EXPECT_EQ(ReadText(out / "frames.csv"), "the user's own frames.csv");
  EXPECT_EQ(CountStaging(out), 0);
  // Names the new set does not write are left alone, in `masks/` too.
  fs::remove(out / "frames.csv");
  CommitSet(out, {{"frames.csv", "new"}, {"masks/0001.png", "new"}});
  EXPECT_EQ(ReadText(out / "features.csv"), "the user's");
  EXPECT_EQ(ReadText(out / "masks/0009.png"), "the user's");
  // And a rerun that writes no masks removes its own, not the user's.
  CommitSet(out, {{"frames.csv", "newer"}});
  EXPECT_FALSE(fs::exists(out / "masks/0001.png"));
  EXPECT_EQ(ReadText(out / "masks/0009.png"), "the user's");
}

TEST(ResultSet, AManifestOrResultThatIsNoRegularFileIsRefusedAtOnce) {
  TempDir dir;
  const fs::path out = dir / "out";
  CommitSet(out, {{"frames.csv", "rows"}});
  fs::remove(out / "frames.csv");
  ASSERT_EQ(::mkfifo((out / "frames.csv").c_str(), 0644), 0);
  EXPECT_THAT(MessageOf([&] { VerifyResultSet(out); }), HasSubstr("not a regular file"));
  fs::remove(out / kManifestName);
  ASSERT_EQ(::mkfifo((out / kManifestName).c_str(), 0644), 0);
  EXPECT_THAT(MessageOf([&] { VerifyResultSet(out); }), HasSubstr("not a regular file"));
}

TEST(ResultSet, ADamagedJournalIsNamedNotFollowed) {
  TempDir dir;
  const fs::path out = dir / "out";
  CommitSet(out, {{"frames.csv", "rows"}});
  for (const std::string& journal :
       {std::string("{\"format\": \"sdoslam result commit\"}"),
        std::string("{\"format\": \"sdoslam result commit\", \"staging\": \"../../etc\", "
                    "\"stale\": []}"),
        std::string("not json")}) {
    WriteText(out / ".sdoslam-commit.json", journal);
    const std::string message = MessageOf([&] { VerifyResultSet(out); });
    EXPECT_TRUE(message.find("is damaged") != std::string::npos ||
                message.find("names no staging folder") != std::string::npos)
        << message;
    EXPECT_EQ(ReadText(out / "frames.csv"), "rows");
  }
}

TEST(ResultSet, AMasksFolderThatLinksElsewhereIsNeverWrittenThroughNorEmptied) {
  TempDir dir;
  const fs::path out = dir / "out";
  WriteText(dir / "photos" / "0001.png", "a photo");
  WriteText(dir / "photos" / "holiday.png", "another");
  CommitSet(out, {{"frames.csv", "old"}, {"masks/0001.png", "old mask"}});
  fs::remove_all(out / "masks");
  fs::create_directory_symlink(dir / "photos", out / "masks");
  {
    ResultSetWriter writer(out);
    writer.WriteText("frames.csv", "new");
    writer.WriteText("masks/0001.png", "new mask");
    EXPECT_THAT(MessageOf([&] { writer.Commit("complete", {}); }), HasSubstr("symbolic link"));
  }
  // No masks this time: the old set's masks/0001.png is stale.
  CommitSet(out, {{"frames.csv", "new"}});
  EXPECT_EQ(ReadText(dir / "photos" / "0001.png"), "a photo");
  EXPECT_EQ(ReadText(dir / "photos" / "holiday.png"), "another");
  EXPECT_TRUE(fs::is_symlink(out / "masks"));
}

TEST(ResultSet, AFolderInPlaceOfAResultFileIsRefusedBeforeTheOldSetIsTouched) {
  TempDir dir;
  const fs::path out = dir / "out";
  CommitSet(out, {{"CameraTrajectory.txt", "old trajectory"},
                  {"mapping.csv", "old mapping"},
                  {"loops.csv", "old loops"}});
  fs::remove(out / "loops.csv");
  fs::create_directory(out / "loops.csv");
  {
    ResultSetWriter writer(out);
    writer.WriteText("CameraTrajectory.txt", "new trajectory");
    writer.WriteText("mapping.csv", "new mapping");
    writer.WriteText("loops.csv", "new loops");
    EXPECT_THAT(MessageOf([&] { writer.Commit("complete", {}); }),
                HasSubstr("loops.csv is in the way"));
  }
  // The old manifest is still there and the old files with it: no mix of old and new.
  EXPECT_EQ(ReadText(out / "CameraTrajectory.txt"), "old trajectory");
  EXPECT_EQ(ReadText(out / "mapping.csv"), "old mapping");
  EXPECT_THAT(MessageOf([&] { VerifyResultSet(out); }), HasSubstr("loops.csv"));
}

TEST(ResultSet, WithoutCommitTheOldSetStaysUntouchedAndNoStagingIsLeft) {
  TempDir dir;
  const fs::path out = dir / "out";
  CommitSet(out, {{"frames.csv", "old"}});
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
  { ResultSetWriter writer(dir / "new" / "a" / "out"); }
  EXPECT_FALSE(fs::exists(dir / "new"));
  // Nor when the writer itself fails: `o` exists, `o/a/b` would be created, the lock is taken.
  WriteText(dir / "o" / "keep.txt", "mine");
  {
    ResultSetWriter first(dir / "o" / "a" / "b");
    EXPECT_THAT(MessageOf([&] { ResultSetWriter second(dir / "o" / "a" / "b"); }),
                HasSubstr("another sdoslam run"));
  }
  EXPECT_FALSE(fs::exists(dir / "o" / "a"));
  EXPECT_EQ(ReadText(dir / "o" / "keep.txt"), "mine");
}

// The old and the new set of the crash tests: some names in both, some in one only.
const std::map<std::string, std::string> kOldSet = {{"CameraTrajectory.txt", "old trajectory"},
                                                    {"frames.csv", "old frames"},
                                                    {"masks/0001.png", "old mask 1"},
                                                    {"masks/0002.png", "old mask 2"},
                                                    {"overlays/0001.png", "old overlay"}};
const std::map<std::string, std::string> kNewSet = {{"CameraTrajectory.txt", "new trajectory"},
                                                    {"frames.csv", "new frames"},
                                                    {"loops.csv", "new loops"},
                                                    {"masks/0001.png", "new mask 1"}};

// What the manifest vouches for, read back: relative path -> content.
std::map<std::string, std::string> VerifiedSet(const fs::path& out) {
  std::map<std::string, std::string> found;
  for (const ResultFileEntry& f : VerifyResultSet(out).files)
    found[f.path] = ReadText(out / f.path);
  return found;
}

TEST(ResultSet, AKillAtAnyStepOfTheCommitLeavesTheOldSetOrTheNewOneNeverAMix) {
  int killed = 0;
  for (int step = 1; step < 60; ++step) {
    TempDir dir;
    const fs::path out = dir / "out";
    CommitSet(out, kOldSet);
    const pid_t pid = ::fork();
    if (pid == 0) {
      try {
        CommitSet(out, kNewSet, step);
      } catch (...) {
        ::_exit(3);
      }
      ::_exit(0);
    }
    int status = 0;
    ::waitpid(pid, &status, 0);
    const bool was_killed = WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL;
    if (!was_killed) {
      ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    }
    // A reader (eval) finishes a commit that was decided, and then reads it whole.
    const auto set = VerifiedSet(out);
    // Step 1 comes before the journal: the commit was not decided, the old set stands.
    EXPECT_EQ(set, step == 1 ? kOldSet : kNewSet) << "killed at step " << step;
    if (step > 1) {
      // Nothing is left over: no stale mask, no staging folder, no journal.
      EXPECT_FALSE(fs::exists(out / "masks/0002.png")) << step;
      EXPECT_FALSE(fs::exists(out / "overlays")) << step;
      EXPECT_EQ(CountStaging(out), 0) << step;
      EXPECT_FALSE(fs::exists(out / ".sdoslam-commit.json")) << step;
    }
    // And the next run into the folder commits as usual, and tidies up.
    CommitSet(out, kOldSet);
    EXPECT_EQ(VerifiedSet(out), kOldSet) << step;
    EXPECT_EQ(CountStaging(out), 0) << step;
    if (!was_killed) break;
    ++killed;
  }
  EXPECT_GE(killed, 10);  // the journal, the old manifest, each rename and removal
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
  CommitSet(out, {{"CameraTrajectory.txt", "1 0 0 0 0 0 0 1\n"}, {"frames.csv", "index\n"}});
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
