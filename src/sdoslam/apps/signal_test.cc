// Interrupts real `sdoslam run` processes at random moments and checks what a user finds in
// --out afterwards: always one complete result set (the earlier one or the new one, never a mix),
// and an interrupted run's partial trajectory that evaluates.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <thread>
#include <tuple>

#include "sdoslam/io/output_folder.h"
#include "sdoslam/io/result_set.h"
#include "sdoslam/io/trajectory.h"
#include "sdoslam/testing/test_util.h"

extern char** environ;

namespace sdoslam {
namespace {
namespace fs = std::filesystem;

struct Outcome {
  bool exited = false;  // false: killed by the signal (it came before the handler was installed)
  int code = -1;
};

// Starts `sdoslam` with `arguments` (output discarded), sends `signals` after `delay`, waits.
Outcome RunAndSignal(const std::vector<std::string>& arguments, std::chrono::milliseconds delay,
                     const std::vector<int>& signals) {
  std::vector<std::string> all = {SDOSLAM_EXECUTABLE};
  all.insert(all.end(), arguments.begin(), arguments.end());
  std::vector<char*> argv;
  for (std::string& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) return {};
  std::this_thread::sleep_for(delay);
  for (size_t k = 0; k < signals.size(); ++k) {
    // A second signal sent while the first is still pending would merge with it.
    if (k > 0) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    ::kill(pid, signals[k]);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  Outcome outcome;
  outcome.exited = WIFEXITED(status);
  outcome.code = outcome.exited ? WEXITSTATUS(status) : WTERMSIG(status);
  return outcome;
}

class Interrupts : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { dir_ = new testing::TempDir; }
  static void TearDownTestSuite() { delete dir_; }
  // A walking_xyz sequence of `frames` frames, rendered on first use. ctest runs each test in a
  // process of its own, so each renders what it needs and no more (150 frames take ~11 s).
  static fs::path Seq(int frames) {
    const fs::path seq = *dir_ / ("seq_" + std::to_string(frames));
    if (!fs::exists(seq)) {
      const Outcome synth = RunAndSignal({"synth", "--scenario", "walking_xyz", "--frames",
                                          std::to_string(frames), "--out", seq.string()},
                                         std::chrono::milliseconds(0), {});
      EXPECT_TRUE(synth.exited && synth.code == 0);
    }
    return seq;
  }
  static testing::TempDir* dir_;
};
testing::TempDir* Interrupts::dir_ = nullptr;

TEST_F(Interrupts, TwentyRandomInterruptsLeaveTheOldSetOrTheNewNeverAMix) {
  const fs::path out = *dir_ / "out", seq = Seq(150);
  const std::vector<std::string> run = {
      "run",   "--dataset",  seq.string(),   "--config",    (seq / "camera.yaml").string(),
      "--out", out.string(), "--sequential", "--save-masks"};
  std::mt19937 random(17);
  std::uniform_int_distribution<int> delay_ms(150, 2500);
  int interrupted_sets = 0, evaluated = 0, aborted = 0;
  for (int trial = 0; trial < 20; ++trial) {
    SCOPED_TRACE("trial " + std::to_string(trial));
    const std::string before =
        fs::exists(out / kManifestName) ? testing::ReadText(out / kManifestName) : "";
    // Every fourth trial signals twice (abort); every third uses SIGTERM.
    const int signal = trial % 3 == 2 ? SIGTERM : SIGINT;
    const bool twice = trial % 4 == 3;
    const Outcome o =
        RunAndSignal(run, std::chrono::milliseconds(delay_ms(random)),
                     twice ? std::vector<int>{signal, signal} : std::vector<int>{signal});
    const std::string after =
        fs::exists(out / kManifestName) ? testing::ReadText(out / kManifestName) : "";
    if (!after.empty()) {
      // Whatever happened, the folder holds one set whose files all match its manifest.
      EXPECT_NO_THROW(VerifyResultSet(out));
    }
    if (!o.exited) {
      // Killed by the signal's default action. Either it came before the handler was installed,
      // and the earlier set is untouched; or it came after the run had written its set and given
      // the handler back (the process was on its way out), and the folder holds that whole new
      // set, verified above. A kill in between cannot happen: the handler defers an abort during
      // the commit.
      if (after != before) {
        ASSERT_FALSE(after.empty());
        // With one signal, a new set means the run had finished before the signal came.
        if (!twice) {
          EXPECT_EQ(VerifyResultSet(out).status, "complete");
        }
      }
      continue;
    }
    if (twice && o.code != 0 && after == before) {
      ++aborted;  // the second signal came before the commit began: nothing was written
      continue;
    }
    // Otherwise the second signal came during the commit, which it does not cut: a new set.
    ASSERT_TRUE(o.code == 0 || o.code == 128 + signal) << "exit code " << o.code;
    ASSERT_FALSE(after.empty());
    const ResultManifest m = VerifyResultSet(out);
    if (o.code == 0) {
      EXPECT_EQ(m.status, "complete");
      continue;
    }
    EXPECT_EQ(m.status, "interrupted");
    ++interrupted_sets;
    const size_t processed = m.info.at("frames_processed").get<size_t>();
    EXPECT_LE(processed, 150u);  // all of them when the signal came during the last frame
    // The partial trajectory is a valid TUM file with a pose per tracked frame.
    const Trajectory partial = ReadTumTrajectory(out / "CameraTrajectory.txt");
    EXPECT_EQ(partial.size(), m.info.at("frames_tracked").get<size_t>());
    if (partial.size() >= 3) {
      const Outcome eval =
          RunAndSignal({"eval", "--gt", (seq / "groundtruth.txt").string(), "--est",
                        (out / "CameraTrajectory.txt").string(), "--no-plots"},
                       std::chrono::milliseconds(0), {});
      EXPECT_TRUE(eval.exited && eval.code == 0);
      ++evaluated;
    }
  }
  // The trials exercised what they are about (not all finished before their signal).
  EXPECT_GE(interrupted_sets, 8);
  EXPECT_GE(evaluated, 5);
  std::cout << interrupted_sets << " interrupted sets (" << evaluated << " evaluated), " << aborted
            << " aborted by a second signal\n";
}

// The files a folder of ours lists in its marker, and those it holds: equal when complete.
std::pair<std::set<std::string>, std::set<std::string>> ListedAndPresent(const fs::path& folder) {
  std::set<std::string> listed, present;
  std::ifstream in(folder / kOutputFolderMarker);
  const nlohmann::json marker = nlohmann::json::parse(in);  // alive through the loop
  for (const auto& f : marker.at("files")) listed.insert(f.get<std::string>());
  for (const auto& e : fs::recursive_directory_iterator(folder)) {
    const std::string name = fs::relative(e.path(), folder).generic_string();
    if (e.is_regular_file() && name != kOutputFolderMarker) present.insert(name);
  }
  return {listed, present};
}

size_t FramesListed(const fs::path& sequence) {
  return ReadTumTrajectory(sequence / "groundtruth.txt").size();
}

int CountHidden(const fs::path& parent) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(parent))
    n += e.path().filename().string().find(".sdoslam-") != std::string::npos;
  return n;
}

// Ctrl-C during `synth --overwrite`: the frames written so far go, the earlier folder stays
// whole, nothing is left beside it, and the exit code says it was interrupted.
TEST_F(Interrupts, AnInterruptedSynthLeavesTheEarlierSequenceAndNothingElse) {
  const fs::path out = *dir_ / "interrupted_synth";
  const Outcome first =
      RunAndSignal({"synth", "--scenario", "static_room", "--frames", "3", "--out", out.string()},
                   std::chrono::milliseconds(0), {});
  ASSERT_TRUE(first.exited && first.code == 0);
  for (const int signal : {SIGINT, SIGTERM}) {
    const Outcome o = RunAndSignal({"synth", "--scenario", "walking_xyz", "--frames", "300",
                                    "--out", out.string(), "--overwrite"},
                                   std::chrono::milliseconds(700), {signal});
    ASSERT_TRUE(o.exited);
    EXPECT_EQ(o.code, 128 + signal);
    EXPECT_EQ(FramesListed(out), 3u);
    EXPECT_EQ(CountHidden(dir_->path()), 0);
  }
}

// Milliseconds that `arguments` takes uninterrupted (a busy machine makes every writer slower:
// kill times are drawn relative to this, so that some kills come before the end and some after).
int DurationMs(const std::vector<std::string>& arguments) {
  const auto start = std::chrono::steady_clock::now();
  const Outcome o = RunAndSignal(arguments, std::chrono::milliseconds(0), {});
  EXPECT_TRUE(o.exited && o.code == 0);
  return static_cast<int>(std::chrono::duration_cast<std::chrono::milliseconds>(
                              std::chrono::steady_clock::now() - start)
                              .count());
}

// SIGKILL (no handler, no clean-up) at random moments of `run`, `synth --overwrite` and
// `convert --overwrite`: the folder holds the earlier complete results or the new complete ones,
// and the next write tidies away what the killed one left beside them.
TEST_F(Interrupts, TwentyRandomKillsOfEachWriterLeaveTheOldResultsOrTheNewOnes) {
  std::mt19937 random(23);
  const fs::path out = *dir_ / "killed_run", seq = Seq(20);
  const std::vector<std::string> run = {
      "run",   "--dataset",  seq.string(),  "--config", (seq / "camera.yaml").string(),
      "--out", out.string(), "--sequential"};
  // Between a third of a run and twice its time (a loaded machine varies): some kills land
  // before the end, some after.
  const auto kill_delay = [&random](int duration_ms) {
    return std::chrono::milliseconds(
        std::uniform_int_distribution<int>(duration_ms / 3, duration_ms * 2)(random));
  };
  const int run_ms = DurationMs(run);
  int run_changed = 0;
  for (int trial = 0; trial < 20; ++trial) {
    SCOPED_TRACE("run trial " + std::to_string(trial));
    const std::string before = testing::ReadText(out / kManifestName);
    RunAndSignal(run, kill_delay(run_ms), {SIGKILL});
    const ResultManifest m = VerifyResultSet(out);  // finishes a commit the kill cut off
    EXPECT_EQ(m.status, "complete");
    run_changed += testing::ReadText(out / kManifestName) != before;
  }

  // synth and convert: frame counts alternate, so the old folder and the new one differ.
  const fs::path synth_out = *dir_ / "killed_synth", copy_out = *dir_ / "killed_copy";
  const auto synth = [&](size_t frames) {
    return std::vector<std::string>{
        "synth", "--scenario",       "walking_static", "--frames", std::to_string(frames),
        "--out", synth_out.string(), "--overwrite"};
  };
  const std::vector<std::string> convert = {"convert", "--dataset",       synth_out.string(),
                                            "--out",   copy_out.string(), "--overwrite"};
  const int synth_ms = DurationMs(synth(4));
  const int convert_ms = DurationMs(convert);
  int synth_replaced = 0, copy_replaced = 0;
  for (int trial = 0; trial < 20; ++trial) {
    SCOPED_TRACE("synth/convert trial " + std::to_string(trial));
    const size_t frames = 3 + trial % 2;
    const size_t before = FramesListed(synth_out);
    RunAndSignal(synth(frames), kill_delay(synth_ms), {SIGKILL});
    auto [listed, present] = ListedAndPresent(synth_out);
    EXPECT_EQ(listed, present);
    const size_t after = FramesListed(synth_out);
    EXPECT_TRUE(after == before || after == frames) << after;
    synth_replaced += after != before;

    const size_t copy_before = FramesListed(copy_out);
    RunAndSignal(convert, kill_delay(convert_ms), {SIGKILL});
    std::tie(listed, present) = ListedAndPresent(copy_out);
    EXPECT_EQ(listed, present);
    const size_t copy_after = FramesListed(copy_out);
    EXPECT_TRUE(copy_after == copy_before || copy_after == after) << copy_after;
    copy_replaced += copy_after != copy_before;
  }
  // The trials exercised both outcomes: kills before the switch and writes that got through.
  EXPECT_GE(run_changed, 2);
  EXPECT_LE(run_changed, 18);
  EXPECT_GE(synth_replaced, 2);
  EXPECT_LE(synth_replaced, 18);
  // What the killed writers left beside their folders goes with the next complete write.
  DurationMs(synth(2));
  DurationMs(convert);
  EXPECT_EQ(CountHidden(dir_->path()), 0);
  std::cout << run_changed << " runs, " << synth_replaced << " synths, " << copy_replaced
            << " converts of 20 got their new results in before the kill\n";
}

}  // namespace
}  // namespace sdoslam
