#include "sdoslam/io/output_folder.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <stdlib.h>
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

OutputFolderOptions Options(bool overwrite, std::vector<fs::path> inputs = {}) {
  OutputFolderOptions options;
  options.kind = "test sequence";
  options.overwrite = overwrite;
  options.inputs = std::move(inputs);
  return options;
}

// Writes `files` (relative path -> content) as a complete folder of ours at `out`.
void WriteOurs(const fs::path& out, const std::map<std::string, std::string>& files,
               bool overwrite = false) {
  OutputFolder folder(out, Options(overwrite));
  for (const auto& [path, content] : files) WriteText(folder.staging() / path, content);
  folder.Commit();
}

std::map<std::string, std::string> Contents(const fs::path& folder) {
  return testing::FilesUnder(folder);
}

// Names in `parent` that a staging folder of `out` would have.
int CountLeftovers(const fs::path& parent) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(parent))
    n += e.path().filename().string().find(".sdoslam-staging-") != std::string::npos;
  return n;
}

const std::map<std::string, std::string> kOld = {
    {"rgb.txt", "old list"}, {"rgb/1.png", "old 1"}, {"rgb/2.png", "old 2"}, {"gt.txt", "old gt"}};
const std::map<std::string, std::string> kNew = {
    {"rgb.txt", "new list"}, {"rgb/1.png", "new 1"}, {"depth/1.png", "new depth"}};

// What a reader finds, without the marker: the old folder's files or the new one's, exactly.
std::map<std::string, std::string> Visible(const fs::path& out) {
  std::map<std::string, std::string> found = Contents(out);
  found.erase(kOutputFolderMarker);
  return found;
}

TEST(OutputFolder, WritesAFolderWithAMarkerThatListsItsFiles) {
  TempDir dir;
  WriteOurs(dir / "a" / "b" / "out", kNew);
  EXPECT_EQ(Visible(dir / "a" / "b" / "out"), kNew);
  const std::string marker = ReadText(dir / "a" / "b" / "out" / kOutputFolderMarker);
  EXPECT_THAT(marker, HasSubstr("\"depth/1.png\""));
  EXPECT_THAT(marker, HasSubstr("test sequence"));
  EXPECT_EQ(CountLeftovers(dir / "a" / "b"), 0);
  RemoveOutputFolder(dir / "a" / "b" / "out", "test sequence");
  EXPECT_FALSE(fs::exists(dir / "a" / "b" / "out"));
}

TEST(OutputFolder, ReplacesItsOwnEarlierFolderOnlyWithOverwrite) {
  TempDir dir;
  const fs::path out = dir / "out";
  WriteOurs(out, kOld);
  EXPECT_THAT(MessageOf([&] { WriteOurs(out, kNew); }), HasSubstr("--overwrite"));
  EXPECT_EQ(Visible(out), kOld);
  WriteOurs(out, kNew, /*overwrite=*/true);
  EXPECT_EQ(Visible(out), kNew);  // rgb/2.png and gt.txt of the old folder are gone
  EXPECT_EQ(CountLeftovers(dir.path()), 0);
}

TEST(OutputFolder, NeverReplacesAFolderItDidNotWrite) {
  TempDir dir;
  const fs::path out = dir / "users";
  WriteText(out / "thesis.tex", "years of work");
  WriteText(out / "data" / "run1.csv", "1,2,3");
  const std::string message = MessageOf([&] { WriteOurs(out, kNew, /*overwrite=*/true); });
  EXPECT_THAT(message, HasSubstr("was not written by sdoslam"));
  EXPECT_EQ(Contents(out).size(), 2u);
  EXPECT_EQ(ReadText(out / "thesis.tex"), "years of work");
  EXPECT_EQ(CountLeftovers(dir.path()), 0);
}

TEST(OutputFolder, RefusesItsOwnFolderOnceTheUserAddedSomethingNamingIt) {
  TempDir dir;
  const fs::path out = dir / "out";
  WriteOurs(out, kOld);
  WriteText(out / "rgb" / "notes.txt", "mine");
  EXPECT_THAT(MessageOf([&] { WriteOurs(out, kNew, true); }), HasSubstr("rgb/notes.txt"));
  EXPECT_EQ(ReadText(out / "rgb" / "notes.txt"), "mine");
  EXPECT_EQ(ReadText(out / "rgb" / "2.png"), "old 2");
}

TEST(OutputFolder, NeverFollowsASymbolicLinkIntoSomeoneElsesFolder) {
  TempDir dir;
  const fs::path out = dir / "out";
  WriteText(dir / "elsewhere" / "precious.txt", "keep");
  WriteOurs(out, kOld);
  // A link where the old folder had a listed file's folder, and a link beside its files.
  fs::rename(out / "rgb", dir / "moved_rgb");
  fs::create_directory_symlink(dir / "elsewhere", out / "rgb");
  EXPECT_THAT(MessageOf([&] { WriteOurs(out, kNew, true); }), HasSubstr("did not write"));
  EXPECT_EQ(ReadText(dir / "elsewhere" / "precious.txt"), "keep");
  // `out` itself a link to a folder: refused, the folder untouched.
  fs::create_directory_symlink(dir / "elsewhere", dir / "link");
  EXPECT_THAT(MessageOf([&] { WriteOurs(dir / "link", kNew, true); }), HasSubstr("symbolic link"));
  EXPECT_EQ(ReadText(dir / "elsewhere" / "precious.txt"), "keep");
}

TEST(OutputFolder, AnOutThatNamesAFileOrAnotherKindIsRefused) {
  TempDir dir;
  WriteText(dir / "file.txt", "a file");
  EXPECT_THAT(MessageOf([&] { WriteOurs(dir / "file.txt", kNew, true); }),
              HasSubstr("names a file"));
  EXPECT_EQ(ReadText(dir / "file.txt"), "a file");
  WriteOurs(dir / "out", kOld);
  OutputFolderOptions other = Options(true);
  other.kind = "TUM copy";
  EXPECT_THAT(MessageOf([&] { OutputFolder folder(dir / "out", other); }),
              HasSubstr("holds a test sequence, not a TUM copy"));
  EXPECT_EQ(Visible(dir / "out"), kOld);
}

TEST(OutputFolder, RefusesTheRootTheHomeFolderAndTheInputsWhereaboutsBeforeAnything) {
  TempDir dir;
  // Pure checks: nothing is written for "/" even if a check were wrong.
  EXPECT_THAT(MessageOf([] { CheckOutputPlace("/", {}, "--out"); }), HasSubstr("root folder"));
  EXPECT_THAT(MessageOf([] { CheckOutputPlace("/tmp/../", {}, "--out"); }),
              HasSubstr("root folder"));
  const fs::path input = dir / "dataset";
  WriteText(input / "rgb" / "1.png", "input");
  const char* old_home = std::getenv("HOME");
  const std::string saved = old_home ? old_home : "";
  ::setenv("HOME", (dir / "home").c_str(), 1);
  WriteText(dir / "home" / ".bashrc", "home");
  const std::string home_message = MessageOf([&] { WriteOurs(dir / "home", kNew, true); });
  if (old_home) {
    ::setenv("HOME", saved.c_str(), 1);
  } else {
    ::unsetenv("HOME");
  }
  EXPECT_THAT(home_message, HasSubstr("home folder"));
  EXPECT_EQ(ReadText(dir / "home" / ".bashrc"), "home");

  auto write_over = [&](const fs::path& out) {
    return MessageOf([&] {
      OutputFolder folder(out, Options(true, {input}));
      folder.Commit();
    });
  };
  EXPECT_THAT(write_over(input), HasSubstr("is the input"));
  EXPECT_THAT(write_over(input / "rgb"), HasSubstr("lies inside the input"));
  EXPECT_THAT(write_over(input / "rgb" / ".." / "new"), HasSubstr("lies inside the input"));
  EXPECT_THAT(write_over(dir.path()), HasSubstr("contains the input"));
  fs::create_directory_symlink(input, dir / "alias");
  EXPECT_THAT(write_over(dir / "alias" / "x"), HasSubstr("lies inside the input"));
  EXPECT_EQ(ReadText(input / "rgb" / "1.png"), "input");
  EXPECT_EQ(CountLeftovers(dir.path()), 0);
}

TEST(OutputFolder, WithoutCommitNothingIsLeftNotEvenTheFoldersItCreated) {
  TempDir dir;
  {
    OutputFolder folder(dir / "o" / "a" / "b", Options(false));
    WriteText(folder.staging() / "rgb.txt", "half");
  }
  EXPECT_FALSE(fs::exists(dir / "o"));
}

// Kills a child process at step `step` of a replacing commit; returns whether the kill came
// (false: the commit has fewer steps and finished).
bool KillDuringReplacement(const fs::path& out, int step) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    try {
      OutputFolder folder(out, Options(true));
      for (const auto& [path, content] : kNew) WriteText(folder.staging() / path, content);
      folder.SetStepHookForTesting([step](int s) {
        if (s == step) ::raise(SIGKILL);
      });
      folder.Commit();
    } catch (...) {
      ::_exit(3);
    }
    ::_exit(0);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  if (WIFEXITED(status)) {
    EXPECT_EQ(WEXITSTATUS(status), 0);
  }
  return WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL;
}

TEST(OutputFolder, AKillAtAnyStepLeavesTheOldFolderOrTheNewOneAndTheNextWriteTidiesUp) {
  TempDir dir;
  const fs::path out = dir / "out";
  int killed = 0;
  for (int step = 1; step < 50; ++step) {
    if (fs::exists(out)) RemoveOutputFolder(out, "test sequence");
    WriteOurs(out, kOld);
    const bool was_killed = KillDuringReplacement(out, step);
    const auto visible = Visible(out);
    EXPECT_TRUE(visible == kOld || visible == kNew) << "step " << step;
    if (step >= 2) {
      EXPECT_EQ(visible, kNew) << "step " << step << ": after the switch";
    }
    if (!was_killed) break;
    ++killed;
    // The next write into the same place removes what the killed one left beside it.
    WriteOurs(out, kOld, /*overwrite=*/true);
    EXPECT_EQ(CountLeftovers(dir.path()), 0) << "step " << step;
  }
  EXPECT_GE(killed, 5);  // sync, switch, and each of the old folder's files
}

}  // namespace
}  // namespace sdoslam
