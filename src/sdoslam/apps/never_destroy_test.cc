// The real `sdoslam` executable, run as a careless script would, never deletes or overwrites a
// file it did not write: --overwrite onto someone else's folder, onto its own input, a `masks`
// that links elsewhere.
#include <gtest/gtest.h>

#include <map>
#include <vector>

#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {
namespace fs = std::filesystem;
using testing::ReadText;
using testing::WriteText;

using Result = testing::CommandResult;

Result Sdoslam(const std::string& arguments) {
  // Appended piece by piece: GCC 12 warns (-Warray-bounds, a false positive) on the sum here.
  std::string command = SDOSLAM_EXECUTABLE;
  command += ' ';
  command += arguments;
  return testing::RunCommand(command);
}

std::map<std::string, std::string> Snapshot(const fs::path& folder) {
  return testing::FilesUnder(folder);
}

class NeverDestroy : public ::testing::Test {
 protected:
  void SetUp() override {
    const Result r = Sdoslam("synth --scenario static_room --frames 12 --out " + Seq());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    WriteText(dir_ / "users" / "thesis.tex", "years of work");
    WriteText(dir_ / "users" / "data" / "run1.csv", "1,2,3");
  }
  std::string Seq() const { return (dir_ / "seq").string(); }
  testing::TempDir dir_;
};

TEST_F(NeverDestroy, SynthAndConvertOverwriteOnlyAFolderTheyWrote) {
  const auto users = Snapshot(dir_ / "users");
  for (const std::string& command :
       std::vector<std::string>{"synth --scenario static_room --frames 2 --overwrite --out ",
                                "convert --dataset " + Seq() + " --overwrite --out "}) {
    SCOPED_TRACE(command);
    Result r = Sdoslam(command + (dir_ / "users").string());
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find("was not written by sdoslam"), std::string::npos) << r.output;
    EXPECT_EQ(Snapshot(dir_ / "users"), users);
    // --out naming a file.
    r = Sdoslam(command + (dir_ / "users" / "thesis.tex").string());
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("names a file"), std::string::npos) << r.output;
    EXPECT_EQ(Snapshot(dir_ / "users"), users);
  }
  // Its own folder it does replace, twice over.
  for (int round = 0; round < 2; ++round) {
    EXPECT_EQ(Sdoslam("synth --scenario static_room --frames 3 --overwrite --out " +
                      (dir_ / "mine").string())
                  .exit_code,
              0);
    EXPECT_EQ(
        Sdoslam("convert --dataset " + Seq() + " --overwrite --out " + (dir_ / "copy").string())
            .exit_code,
        0);
  }
  // Once the user puts a file of their own into it, it is theirs too.
  WriteText(dir_ / "mine" / "notes.txt", "mine now");
  const Result r = Sdoslam("synth --scenario static_room --frames 3 --overwrite --out " +
                           (dir_ / "mine").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("notes.txt"), std::string::npos) << r.output;
  EXPECT_EQ(ReadText(dir_ / "mine" / "notes.txt"), "mine now");
}

TEST_F(NeverDestroy, ConvertNeverWritesOverOrAroundItsInput) {
  const auto input = Snapshot(dir_ / "seq");
  for (const fs::path& out : {dir_ / "seq", dir_ / "seq" / "rgb", dir_.path()}) {
    SCOPED_TRACE(out.string());
    const Result r = Sdoslam("convert --dataset " + Seq() + " --overwrite --out " + out.string());
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find("the input"), std::string::npos) << r.output;
    EXPECT_EQ(Snapshot(dir_ / "seq"), input);
  }
  // synth over a real recording: the recording is its input.
  const Result r = Sdoslam("synth --background " + Seq() + " --scenario carried_box --out " +
                           (dir_ / "seq" / "composited").string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("lies inside the input"), std::string::npos) << r.output;
  EXPECT_EQ(Snapshot(dir_ / "seq"), input);
}

TEST_F(NeverDestroy, RunNeverWritesThroughAMasksFolderThatLinksElsewhere) {
  const std::string run = "run --dataset " + Seq() + " --config " + Seq() +
                          "/camera.yaml --sequential --save-masks --out " + (dir_ / "out").string();
  Result r = Sdoslam(run);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  fs::remove_all(dir_ / "out" / "masks");
  fs::create_directory_symlink(dir_ / "users", dir_ / "out" / "masks");
  const auto users = Snapshot(dir_ / "users");
  r = Sdoslam(run);
  EXPECT_EQ(r.exit_code, 4) << r.output;
  EXPECT_NE(r.output.find("symbolic link"), std::string::npos) << r.output;
  EXPECT_EQ(Snapshot(dir_ / "users"), users);
  // Without --save-masks the run writes no masks: it leaves the link, and what it points to.
  r = Sdoslam("run --dataset " + Seq() + " --config " + Seq() + "/camera.yaml --sequential --out " +
              (dir_ / "out").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(Snapshot(dir_ / "users"), users);
  // A user's file where a result goes is not replaced.
  WriteText(dir_ / "fresh" / "frames.csv", "the user's");
  r = Sdoslam("run --dataset " + Seq() + " --config " + Seq() + "/camera.yaml --sequential --out " +
              (dir_ / "fresh").string());
  EXPECT_EQ(r.exit_code, 4) << r.output;
  EXPECT_EQ(ReadText(dir_ / "fresh" / "frames.csv"), "the user's");
}

}  // namespace
}  // namespace sdoslam
