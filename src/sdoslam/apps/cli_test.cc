// Runs the real `sdoslam` executable as a user would and checks exit codes, messages and files.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <tuple>
#include <utility>
#include <vector>

#include "sdoslam/eval/mask_metrics.h"
#include "sdoslam/io/trajectory.h"
#include "sdoslam/testing/html_references.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

using Result = testing::CommandResult;

Result RunSdoslam(const std::string& arguments) {
  return testing::RunCommand(std::string(SDOSLAM_EXECUTABLE) + " " + arguments);
}

TEST(Cli, HelpListsSubcommands) {
  const Result r = RunSdoslam("--help");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.output.find("eval"), std::string::npos);
  EXPECT_NE(r.output.find("demo"), std::string::npos);
  EXPECT_EQ(RunSdoslam("eval --help").exit_code, 0);
}

TEST(Cli, CommandLineMistakesFailWithAMessage) {
  // Usage errors: exit code 2 (the exit-code table in docs/usage.md).
  Result r = RunSdoslam("");
  EXPECT_EQ(r.exit_code, 2);
  r = RunSdoslam("eval --est x.txt");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("--gt"), std::string::npos) << r.output;
  r = RunSdoslam("eval --gt a --est b --frobnicate");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("frobnicate"), std::string::npos) << r.output;
  r = RunSdoslam("eval --gt a --est b --align affine");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("affine"), std::string::npos) << r.output;
  r = RunSdoslam("--log-level loud demo --out /tmp/x");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("unknown log level 'loud'"), std::string::npos) << r.output;
}

class CliEval : public ::testing::Test {
 protected:
  void SetUp() override {
    gt_ = testing::SharedDir() / "data" / "tum_fr2_desk_50" / "groundtruth.txt";
    if (!std::filesystem::exists(gt_)) GTEST_SKIP() << "no " << gt_;
  }
  std::filesystem::path gt_;
  testing::TempDir dir_;
};

TEST_F(CliEval, RigidlyMovedGroundTruthScoresZeroAndWritesJsonAndPlots) {
  // The real fr2_desk ground truth, moved by a rigid transform, evaluated against itself, and a
  // copy whose positions are pushed 1 cm along the (GT-frame) x axis on every other pose.
  Trajectory gt = ReadTumTrajectory(gt_);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.3, 1, 0.2).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(1, 2, 3);
  Trajectory moved = gt;
  for (auto& p : moved) p.T_world_camera = T * p.T_world_camera;
  WriteTumTrajectory(dir_ / "moved.txt", moved);

  const std::string json = (dir_ / "r.json").string();
  const Result r =
      RunSdoslam("eval --gt " + gt_.string() + " --est " + (dir_ / "moved.txt").string() +
                 " --json " + json + " --plot-dir " + (dir_ / "plots").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("ATE rmse"), std::string::npos);
  EXPECT_NE(r.output.find("RTE trans"), std::string::npos);
  const auto j = nlohmann::json::parse(testing::ReadText(json));
  EXPECT_EQ(j["estimates"][0]["matched_poses"].get<size_t>(), gt.size());
  EXPECT_LT(j["estimates"][0]["ate"]["rmse"].get<double>(), 1e-6);
  EXPECT_LT(j["estimates"][0]["rte"]["translation"]["rmse"].get<double>(), 1e-6);
  EXPECT_TRUE(std::filesystem::exists(dir_ / "plots" / "moved_top.png"));
  EXPECT_TRUE(std::filesystem::exists(dir_ / "plots" / "ate_over_time.svg"));
}

TEST(CliEvalErrors, BadInputEndsInOneClearMessage) {
  testing::TempDir dir_;
  const auto gt_ = dir_ / "gt.txt";
  testing::WriteText(gt_, "100.0 0 0 0 0 0 0 1\n100.1 1 0 0 0 0 0 1\n100.2 1 1 0 0 0 0 1\n");
  Result r = RunSdoslam("eval --no-plots --gt " + gt_.string() + " --est " +
                        (dir_ / "missing.txt").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.output, "error: file not found: " + (dir_ / "missing.txt").string() + "\n");

  testing::WriteText(dir_ / "bad.txt", "1.0 0 0 0 0 0 0 1\n2.0 0 0\n");
  r = RunSdoslam("eval --no-plots --gt " + gt_.string() + " --est " + (dir_ / "bad.txt").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("bad.txt:2: expected 8 columns"), std::string::npos) << r.output;

  testing::WriteText(dir_ / "late.txt",
                     "5.0 0 0 0 0 0 0 1\n6.0 0 0 0 0 0 0 1\n7.0 0 0 0 0 0 0 1\n");
  r = RunSdoslam("eval --no-plots --gt " + gt_.string() + " --est " + (dir_ / "late.txt").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("[5.000000, 7.000000]"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("[100.000000, 100.200000]"), std::string::npos) << r.output;

  testing::WriteText(dir_ / "empty.txt", "# nothing\n");
  r = RunSdoslam("eval --no-plots --gt " + gt_.string() + " --est " +
                 (dir_ / "empty.txt").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("no poses"), std::string::npos) << r.output;

  r = RunSdoslam("eval --no-plots --rte-pairing nearest --gt " + gt_.string() + " --est " +
                 gt_.string());
  EXPECT_EQ(r.exit_code, 2);  // usage: the command line itself
  EXPECT_NE(r.output.find("--rte-pairing"), std::string::npos) << r.output;
}

// The RTE pairing is chosen on the command line and recorded in the JSON.
TEST(CliEvalPairing, RtePairingIsAnOptionAndRecorded) {
  testing::TempDir dir;
  std::string gt_text, est_text;
  for (int k = 0; k < 90; ++k) {
    const double t = 100 + k / 30.0;
    char line[96];
    std::snprintf(line, sizeof line, "%.6f %.6f 0 0 0 0 0 1\n", t, t - 100);
    gt_text += line;
    std::snprintf(line, sizeof line, "%.6f %.6f 0 0 0 0 0 1\n", t, 1.1 * (t - 100));
    if (k < 20 || k > 40) est_text += line;  // lost in between
  }
  testing::WriteText(dir / "gt.txt", gt_text);
  testing::WriteText(dir / "est.txt", est_text);
  for (const std::string pairing : {"tum", "strict"}) {
    const auto json = dir / (pairing + ".json");
    const Result r = RunSdoslam("eval --no-plots --rte-pairing " + pairing + " --gt " +
                                (dir / "gt.txt").string() + " --est " + (dir / "est.txt").string() +
                                " --json " + json.string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    std::ifstream in(json);
    EXPECT_EQ(nlohmann::json::parse(in).at("rte_pairing"), pairing);
  }
}

TEST(CliDemo, RunsWithoutDataAndPrintsResults) {
  testing::TempDir dir;
  const Result r = RunSdoslam("demo --frames 40 --out " + dir.path().string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("ATE rmse"), std::string::npos);
  EXPECT_NE(r.output.find("rendered 40 frames"), std::string::npos);
  EXPECT_TRUE(std::filesystem::exists(dir / "walking_xyz" / "groundtruth.txt"));
  EXPECT_TRUE(
      std::filesystem::exists(dir / "slam" / "static_room_conventional" / "CameraTrajectory.txt"));
  EXPECT_TRUE(std::filesystem::exists(dir / "plots" / "ate_over_time.png"));

  // The report: every image and link resolves relative to it. Images: per run (4) a top view
  // and an error plot, the error of all runs, 6 overlay thumbnails (small, linking to the
  // full-size overlays) and the top view of the sdo run's moving objects, under their scores
  // against the rendered people; the sdo run's config shown.
  const auto report = dir / "report.html";
  ASSERT_TRUE(std::filesystem::exists(report)) << r.output;
  EXPECT_NE(r.output.find(report.string()), std::string::npos) << r.output;
  const std::string html = testing::ReadText(report);
  const auto files = testing::ReferencedFiles(html);
  size_t thumbnails = 0, overlays = 0;
  for (const auto& f : files) {
    ASSERT_FALSE(std::filesystem::path(f).is_absolute()) << f;
    EXPECT_TRUE(std::filesystem::is_regular_file(dir / f)) << f;
    if (f.starts_with("report_files/")) {
      ++thumbnails;
      EXPECT_LE(cv::imread((dir / f).string()).cols, 320) << f;
    }
    overlays += f.starts_with("slam/walking_xyz_sdo/overlays/");
  }
  size_t images = 0;
  for (size_t at = html.find("<img "); at != std::string::npos; at = html.find("<img ", at + 1))
    ++images;
  EXPECT_EQ(images, 4u * 2 + 1 + 6 + 1) << html;
  EXPECT_NE(html.find("plots/objects_top.png"), std::string::npos);
  EXPECT_NE(html.find("<td>person_1</td>"), std::string::npos) << html;
  EXPECT_NE(html.find("<td>person_2</td>"), std::string::npos) << html;
  EXPECT_NE(r.output.find("sdo moving objects:"), std::string::npos) << r.output;
  EXPECT_EQ(thumbnails, 6u) << html;
  EXPECT_EQ(overlays, 6u) << html;
  EXPECT_NE(html.find("mode: sdo"), std::string::npos);  // the config, in its <pre>
  EXPECT_EQ(html.find("<script"), std::string::npos);
  EXPECT_EQ(html.find("://"), std::string::npos);
}

class CliRun : public ::testing::Test {
 protected:
  void SetUp() override {
    // A short synthetic sequence to run on.
    const Result r =
        RunSdoslam("synth --scenario static_room --frames 35 --out " + (dir_ / "seq").string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  std::string Run(const std::string& config, const std::string& dataset) {
    last_ = RunSdoslam("run --dataset " + dataset + " --config " + config + " --out " +
                       (dir_ / "out").string());
    return last_.output;
  }
  testing::TempDir dir_;
  Result last_;
};

TEST_F(CliRun, WritesTrajectoriesLogAndEvaluates) {
  const std::string output = Run((dir_ / "seq" / "camera.yaml").string(), (dir_ / "seq").string());
  ASSERT_EQ(last_.exit_code, 0) << output;
  EXPECT_NE(output.find("35 frames: 35 tracked, 0 lost"), std::string::npos) << output;
  EXPECT_NE(output.find("ATE rmse"), std::string::npos);
  for (const char* f :
       {"CameraTrajectory.txt", "KeyFrameTrajectory.txt", "config.yaml", "frames.csv"}) {
    EXPECT_TRUE(std::filesystem::exists(dir_ / "out" / f)) << f;
  }
  EXPECT_EQ(ReadTumTrajectory(dir_ / "out" / "CameraTrajectory.txt").size(), 35u);
  // The resolved config is itself a valid config.
  const Result again = RunSdoslam("run --dataset " + (dir_ / "seq").string() + " --config " +
                                  (dir_ / "out" / "config.yaml").string() +
                                  " --max-frames 5 --out " + (dir_ / "out2").string());
  EXPECT_EQ(again.exit_code, 0) << again.output;
}

// The user's round: a sequence written as an OMD segment, run by path with the shipped OMD
// config (intrinsics from its kalibr.yaml), converted back to TUM; wrong layouts are named.
TEST_F(CliRun, OmdSegmentsRunByPathAndConvertToTum) {
  const std::string omd = (dir_ / "omd").string();
  Result r = RunSdoslam("synth --scenario static_room --frames 35 --layout omd --out " + omd);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string config = (testing::SourceDir() / "configs" / "omd.yaml").string();
  r = RunSdoslam("run --dataset " + omd + " --config " + config + " --out " +
                 (dir_ / "out_omd").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("35 frames: 35 tracked, 0 lost"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("ATE rmse"), std::string::npos) << r.output;  // from vicon.csv
  EXPECT_NE(testing::ReadText(dir_ / "out_omd" / "config.yaml").find("fx: 535.39"),
            std::string::npos);  // the resolved intrinsics are recorded

  r = RunSdoslam("convert --dataset " + omd + " --to tum --out " + (dir_ / "as_tum").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(ReadTumTrajectory(dir_ / "as_tum" / "groundtruth.txt").size(), 35u);
  r = RunSdoslam("run --dataset " + (dir_ / "as_tum").string() + " --config " +
                 (dir_ / "as_tum" / "camera.yaml").string() + " --max-frames 5 --out " +
                 (dir_ / "out_tum").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;

  r = RunSdoslam("run --dataset " + (dir_ / "seq").string() + " --layout omd --config " + config +
                 " --out " + (dir_ / "out_bad").string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("not an OMD segment (no rgbd/rgbd.csv)"), std::string::npos) << r.output;
}

TEST_F(CliRun, SequentialTwiceGivesIdenticalTrajectoryFiles) {
  std::string files[2];
  for (int k = 0; k < 2; ++k) {
    const std::string out = (dir_ / ("det" + std::to_string(k))).string();
    const Result r =
        RunSdoslam("run --sequential --dataset " + (dir_ / "seq").string() + " --config " +
                   (dir_ / "seq" / "camera.yaml").string() + " --out " + out);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    files[k] = testing::ReadText(out + "/CameraTrajectory.txt") +
               testing::ReadText(out + "/KeyFrameTrajectory.txt");
  }
  EXPECT_GT(files[0].size(), 35u * 40u);
  EXPECT_EQ(files[0], files[1]);
}

// Local mapping runs in its own thread unless --sequential or the config's run: section asks
// otherwise; the resolved config.yaml records which.
TEST_F(CliRun, MapsInAThreadByDefaultAndSequentiallyWhenAsked) {
  const std::string common = "run --max-frames 5 --dataset " + (dir_ / "seq").string();
  const std::string camera = (dir_ / "seq" / "camera.yaml").string();
  auto sequential_recorded = [&](const std::string& args, const std::string& name) {
    const Result r = RunSdoslam(common + " " + args + " --out " + (dir_ / name).string());
    EXPECT_EQ(r.exit_code, 0) << r.output;
    const std::string config = testing::ReadText(dir_ / name / "config.yaml");
    if (config.find("sequential: true") != std::string::npos) return 1;
    if (config.find("sequential: false") != std::string::npos) return 0;
    return -1;
  };
  EXPECT_EQ(sequential_recorded("--config " + camera, "threaded"), 0);
  EXPECT_EQ(sequential_recorded("--sequential --config " + camera, "flag"), 1);
  testing::WriteText(dir_ / "seq_run.yaml", testing::ReadText(dir_ / "seq" / "camera.yaml") +
                                                "run:\n  sequential: true\n");
  EXPECT_EQ(sequential_recorded("--config " + (dir_ / "seq_run.yaml").string(), "config"), 1);
}

TEST_F(CliRun, ImpossibleIntrinsicsAndUnknownKeysAreNamed) {
  testing::WriteText(dir_ / "bad.yaml", "camera:\n  fx: -500\n  fy: 500\n  cx: 320\n  cy: 240\n");
  std::string output = Run((dir_ / "bad.yaml").string(), (dir_ / "seq").string());
  EXPECT_EQ(last_.exit_code, 1);
  EXPECT_NE(output.find("camera.fx: focal length must be within"), std::string::npos) << output;
  // Finite but no camera: this ran, exited 0 and wrote a trajectory that meant nothing.
  testing::WriteText(dir_ / "huge.yaml", "camera:\n  fx: 1e308\n  fy: 500\n  cx: 320\n  cy: 240\n");
  output = Run((dir_ / "huge.yaml").string(), (dir_ / "seq").string());
  EXPECT_EQ(last_.exit_code, 1) << output;
  EXPECT_NE(output.find("huge.yaml: camera.fx: focal length must be within"), std::string::npos)
      << output;
  testing::WriteText(dir_ / "typo.yaml",
                     testing::ReadText(dir_ / "seq" / "camera.yaml") + "orb:\n  nfeatures: 5\n");
  output = Run((dir_ / "typo.yaml").string(), (dir_ / "seq").string());
  EXPECT_EQ(last_.exit_code, 1);
  EXPECT_NE(output.find("unknown key 'orb.nfeatures'"), std::string::npos) << output;
  EXPECT_FALSE(std::filesystem::exists(dir_ / "out" / "CameraTrajectory.txt"));
}

TEST_F(CliRun, BenchTimesTheFrontEndInSdoModeAndRejectsUnknownBackends) {
  const std::string common = "bench --runs 2 --dataset " + (dir_ / "seq").string() + " --config " +
                             (dir_ / "seq" / "camera.yaml").string() + " --work " +
                             (dir_ / "bench").string();
  Result r = RunSdoslam(common + " --mode sdo --detector none");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("run 2: "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("mode sdo, 2 runs"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("front end "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("detect 0.0 [none], flow"), std::string::npos) << r.output;
  r = RunSdoslam(common + " --mode sdo --detector yolo9000");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("yolo9000"), std::string::npos) << r.output;
}

// The cells of a Markdown table's rows ("| a | b |" lines; the separator row too), trimmed.
std::vector<std::vector<std::string>> MarkdownRows(const std::string& text) {
  std::vector<std::vector<std::string>> rows;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    if (line.size() < 2 || line.front() != '|' || line.back() != '|') continue;
    std::vector<std::string> cells;
    for (size_t begin = 1, end; (end = line.find('|', begin)) != std::string::npos;
         begin = end + 1) {
      const std::string cell = line.substr(begin, end - begin);
      const size_t first = cell.find_first_not_of(' '), last = cell.find_last_not_of(' ');
      cells.push_back(first == std::string::npos ? "" : cell.substr(first, last - first + 1));
    }
    rows.push_back(cells);
  }
  return rows;
}

// "12.3", "12.3 (11.0–14.2)" or "12.3 / 15.1": the numbers in it; none for "–" or "n/a".
std::vector<double> NumbersIn(const std::string& cell) {
  std::vector<double> numbers;
  const char* p = cell.c_str();
  while (*p != '\0') {
    char* end = nullptr;
    const double value = std::strtod(p, &end);
    if (end != p) {
      numbers.push_back(value);
      p = end;
    } else {
      ++p;
    }
  }
  return numbers;
}

// ATE and RTE RMSE (mm) of a run's CameraTrajectory.txt, as `sdoslam eval` computes them.
std::pair<double, double> EvalMillimetres(const std::filesystem::path& gt,
                                          const std::filesystem::path& run) {
  const auto json = run / "eval.json";
  const Result r = RunSdoslam("eval --no-plots --gt " + gt.string() + " --est " +
                              (run / "CameraTrajectory.txt").string() + " --json " + json.string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  const auto j = nlohmann::json::parse(testing::ReadText(json))["estimates"][0];
  return {1000 * j["ate"]["rmse"].get<double>(),
          1000 * j["rte"]["translation"]["rmse"].get<double>()};
}

// sequences × modes → one Markdown table: one row per (sequence, mode) in the order given, the
// oracle row of a sequence without ground-truth masks n/a, ATE and RTE what `sdoslam eval` says
// of the runs' own trajectories, tracked counts what the trajectories hold.
TEST_F(CliRun, BenchMatrixWritesOneRowPerSequenceAndMode) {
  namespace fs = std::filesystem;
  const fs::path no_masks = dir_ / "no_masks";
  fs::copy(dir_ / "seq", no_masks, fs::copy_options::recursive);
  fs::remove_all(no_masks / "dynamic");
  const fs::path work = dir_ / "bench", table = dir_ / "tables" / "matrix.md";
  const Result r = RunSdoslam("bench --runs 2 --frames 40 --sequences synth:walking_xyz," +
                              no_masks.string() + " --modes conventional,oracle --work " +
                              work.string() + " --table " + table.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string text = testing::ReadText(table);
  EXPECT_NE(r.output.find(text), std::string::npos) << "the table is printed as written";
  EXPECT_NE(text.find("2 runs per row, sequential mapping"), std::string::npos) << text;

  const auto rows = MarkdownRows(text);
  ASSERT_EQ(rows.size(), 2u + 4u) << text;
  EXPECT_EQ(rows[0], (std::vector<std::string>{"sequence", "mode", "ATE RMSE mm", "RTE RMSE mm",
                                               "front end ms", "features + tracking ms",
                                               "mapping ms/keyframe", "fps", "latency ms",
                                               "peak RSS MB", "tracked/frames"}));
  EXPECT_EQ(rows[1], std::vector<std::string>(11, "---")) << text;
  struct Expected {
    std::string sequence, mode;
    fs::path ground_truth, runs;  // the runs: run0, run1
    size_t frames;
  };
  const fs::path synthetic = work / "walking_xyz_xyz_40";
  const std::vector<Expected> expected = {
      {"synth:walking_xyz:xyz", "conventional", synthetic / "groundtruth.txt",
       work / "matrix" / "01_walking_xyz_xyz" / "conventional", 40},
      {"synth:walking_xyz:xyz", "oracle", synthetic / "groundtruth.txt",
       work / "matrix" / "01_walking_xyz_xyz" / "oracle", 40},
      {no_masks.string(), "conventional", no_masks / "groundtruth.txt",
       work / "matrix" / "02_no_masks" / "conventional", 35},
  };
  for (size_t k = 0; k < expected.size(); ++k) {
    const Expected& e = expected[k];
    const std::vector<std::string>& row = rows[2 + k];
    SCOPED_TRACE(e.sequence + " " + e.mode);
    ASSERT_EQ(row.size(), 11u) << text;
    EXPECT_EQ(row[0], e.sequence);
    EXPECT_EQ(row[1], e.mode);
    // ATE and RTE: median (min–max) over the two runs, as `eval` scores each run's trajectory.
    const auto [ate0, rte0] = EvalMillimetres(e.ground_truth, e.runs / "run0");
    const auto [ate1, rte1] = EvalMillimetres(e.ground_truth, e.runs / "run1");
    const double rounding = 0.05 + 1e-9;  // the cells have one decimal
    for (const auto& [cell, first, second] :
         {std::tuple{row[2], ate0, ate1}, std::tuple{row[3], rte0, rte1}}) {
      const std::vector<double> numbers = NumbersIn(cell);
      ASSERT_EQ(numbers.size(), 3u) << cell;
      EXPECT_NEAR(numbers[0], (first + second) / 2, rounding) << cell;
      EXPECT_NEAR(numbers[1], std::min(first, second), rounding) << cell;
      EXPECT_NEAR(numbers[2], std::max(first, second), rounding) << cell;
    }
    EXPECT_EQ(row[4], "–") << "no front end in mode " << e.mode;
    for (const std::string& cell : {row[5], row[6]}) {  // median / p95
      const std::vector<double> numbers = NumbersIn(cell);
      ASSERT_EQ(numbers.size(), 2u) << cell;
      EXPECT_GT(numbers[0], 0) << cell;
      EXPECT_LE(numbers[0], numbers[1]) << cell;
    }
    const std::vector<double> fps = NumbersIn(row[7]);
    ASSERT_EQ(fps.size(), 1u) << row[7];
    EXPECT_GT(fps[0], 0.5);
    const std::vector<double> latency = NumbersIn(row[8]);
    ASSERT_EQ(latency.size(), 1u) << row[8];
    EXPECT_GT(latency[0], 0);
    // Sequential: a frame's latency is its own time, which in a run where nothing overlaps is
    // about the time between frames (1 / fps; that one also holds mapping and logging).
    EXPECT_LT(latency[0], 1.5 * 1000.0 / fps[0]) << row[7] << " fps";
    const std::vector<double> rss = NumbersIn(row[9]);
    ASSERT_EQ(rss.size(), 1u) << row[9];
    EXPECT_GT(rss[0], 20);  // OpenCV, Ceres and 640×480 images: never less
    EXPECT_LT(rss[0], 4096);
    const size_t tracked = ReadTumTrajectory(e.runs / "run0" / "CameraTrajectory.txt").size();
    EXPECT_EQ(tracked, ReadTumTrajectory(e.runs / "run1" / "CameraTrajectory.txt").size());
    EXPECT_EQ(row[10], std::to_string(tracked) + "/" + std::to_string(e.frames));
  }
  EXPECT_EQ(rows[5], (std::vector<std::string>{no_masks.string(), "oracle", "n/a", "n/a", "n/a",
                                               "n/a", "n/a", "n/a", "n/a", "n/a", "n/a"}));
  EXPECT_FALSE(fs::exists(work / "matrix" / "02_no_masks" / "oracle"));
}

// Every item is checked before anything is rendered or run; the message names the bad one.
TEST(CliBenchMatrix, BadInputIsNamedBeforeAnythingRuns) {
  testing::TempDir dir;
  // Small enough that a case which wrongly passes the checks costs seconds, not minutes.
  const std::string work = " --frames 10 --runs 1 --work " + (dir / "work").string();
  std::filesystem::create_directories(dir / "no_config");
  const std::string no_config = (dir / "no_config").string();
  const std::string missing = (dir / "missing").string();
  for (const auto& [arguments, message] : std::vector<std::pair<std::string, std::string>>{
           {"--sequences synth:static_room --modes conventional,fast",
            "--modes: unknown mode 'fast' (known: conventional, sdo, oracle)"},
           {"--sequences synth:static_room,synth:nosuch",
            "--sequences item 'synth:nosuch': unknown scenario 'nosuch'"},
           {"--sequences synth:static_room:wobble",
            "--sequences item 'synth:static_room:wobble': unknown camera motion 'wobble'"},
           {"--sequences synth:static_room," + missing,
            "--sequences item '" + missing + "': no such folder"},
           {"--sequences " + no_config,
            "--sequences item '" + no_config + "': no config: give --config"},
           {"--sequences ''", "--sequences: an empty item"},
           {"--sequences synth:static_room,synth:static_room:xyz",
            "--sequences item 'synth:static_room:xyz': listed twice"},
           {"--sequences synth:static_room --modes ''", "--modes: an empty item"},
           {"--sequences synth:static_room --config " + no_config + "/camera.yaml",
            "--config is for the dataset folders in --sequences, and there is none"},
       }) {
    const Result r = RunSdoslam("bench" + work + " " + arguments);
    EXPECT_EQ(r.exit_code, 1) << arguments << "\n" << r.output;
    EXPECT_NE(r.output.find("error: " + message), std::string::npos) << arguments << "\n"
                                                                     << r.output;
    EXPECT_EQ(r.output.find("rendering"), std::string::npos) << arguments << "\n" << r.output;
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "work"));
  // A --table that cannot be written is an I/O error, also found before the first run.
  const Result r =
      RunSdoslam("bench" + work + " --sequences synth:static_room --table /proc/self/t.md");
  EXPECT_EQ(r.exit_code, 4) << r.output;
  EXPECT_NE(r.output.find("error: --table /proc/self/t.md: cannot write"), std::string::npos)
      << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "work"));
  // The single-sequence options do not mix with the matrix: usage errors.
  for (const std::string& arguments : std::vector<std::string>{
           "--sequences synth:static_room --dataset " + no_config,
           "--sequences synth:static_room --mode sdo", "--modes sdo", "--table t.md"}) {
    const Result r = RunSdoslam("bench" + work + " " + arguments);
    EXPECT_EQ(r.exit_code, 2) << arguments << "\n" << r.output;
  }
}

TEST_F(CliRun, OnnxBackendsAreChosenOnTheCommandLine) {
  const std::string onnx = (testing::SourceDir() / "testdata" / "onnx").string();
  const std::string base = "run --sequential --max-frames 12 --dataset " + (dir_ / "seq").string() +
                           " --config " + (dir_ / "seq" / "camera.yaml").string() +
                           " --mode sdo --segmenter onnx-yoloseg --detector yolov8 --flow onnx";
  Result r = RunSdoslam(base + " --segmenter-model " + onnx + "/yoloseg_tiny.onnx" +
                        " --detector-model " + onnx + "/yolov8_tiny.onnx --flow-model " + onnx +
                        "/flow_stacked_tiny.onnx --out " + (dir_ / "onnx").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("12 frames: 12 tracked"), std::string::npos) << r.output;
  const std::string config = testing::ReadText(dir_ / "onnx" / "config.yaml");
  EXPECT_NE(config.find("flow_stacked_tiny.onnx"), std::string::npos) << config;
  // The segmenter's model given as the flow's: refused before the first frame.
  r = RunSdoslam(base + " --segmenter-model " + onnx + "/yoloseg_tiny.onnx" + " --detector-model " +
                 onnx + "/yolov8_tiny.onnx --flow-model " + onnx + "/yoloseg_tiny.onnx --out " +
                 (dir_ / "bad").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("yoloseg_tiny.onnx"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir_ / "bad" / "CameraTrajectory.txt"));
}

TEST_F(CliRun, EmptySequenceAndNoDepthAtTheStartAreClearErrors) {
  testing::WriteText(dir_ / "seq" / "rgb.txt", "# no frames\n");
  std::string output = Run((dir_ / "seq" / "camera.yaml").string(), (dir_ / "seq").string());
  EXPECT_EQ(last_.exit_code, 1);
  EXPECT_NE(output.find("rgb.txt: no frames listed"), std::string::npos) << output;

  const Result fresh = RunSdoslam("synth --scenario static_room --frames 31 --no-noise --out " +
                                  (dir_ / "nodepth").string());
  ASSERT_EQ(fresh.exit_code, 0);
  for (const auto& entry : std::filesystem::directory_iterator(dir_ / "nodepth" / "depth")) {
    cv::imwrite(entry.path().string(), cv::Mat::zeros(480, 640, CV_16UC1));
  }
  output = Run((dir_ / "nodepth" / "camera.yaml").string(), (dir_ / "nodepth").string());
  EXPECT_EQ(last_.exit_code, 1);
  EXPECT_NE(output.find("the first 30 frames have too little depth to start the map"),
            std::string::npos)
      << output;
}

// The exit-code table in docs/usage.md, row by row (130 and 143: signal_test; 3 is for bugs).
TEST_F(CliRun, ExitCodesFollowTheReadmeTable) {
  const std::string seq = (dir_ / "seq").string();
  const std::string config = (dir_ / "seq" / "camera.yaml").string();
  const std::string out = (dir_ / "out").string();
  Result r = RunSdoslam("run --dataset " + seq + " --config " + config + " --out " + out +
                        " --max-frames 3");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  r = RunSdoslam("run --dataset " + seq + " --config " + config + " --out " + out +
                 " --frobnicate");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  r = RunSdoslam("run --config " + config + " --out " + out);  // no dataset anywhere
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--dataset"), std::string::npos) << r.output;
  r = RunSdoslam("run --dataset " + (dir_ / "nowhere").string() + " --config " + config +
                 " --out " + out);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  // An unwritable --out is an I/O error, found before the first frame.
  r = RunSdoslam("run --dataset " + seq + " --config " + config + " --out /proc/self");
  EXPECT_EQ(r.exit_code, 4) << r.output;
  EXPECT_NE(r.output.find("cannot write into the output folder /proc/self"), std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("frames:"), std::string::npos) << r.output;
  // The failed runs left the earlier complete set as it was.
  EXPECT_EQ(ReadTumTrajectory(dir_ / "out" / "CameraTrajectory.txt").size(), 3u);
}

// An empty --out is a slip on the command line (an unset variable), a usage error (2) on every
// command that writes a folder, not the I/O error (4) that creating "" gave.
TEST_F(CliRun, AnEmptyOutputFolderIsAUsageError) {
  const std::string seq = (dir_ / "seq").string();
  const std::string config = (dir_ / "seq" / "camera.yaml").string();
  for (const std::string& command :
       {"run --dataset " + seq + " --config " + config + " --out ''",
        std::string("synth --scenario static_room --frames 10 --out ''"),
        "convert --dataset " + seq + " --to tum --out ''", std::string("demo --out ''"),
        std::string("bench --work ''"), "vocab build --images " + seq + " --out ''"}) {
    const Result r = RunSdoslam(command);
    EXPECT_EQ(r.exit_code, 2) << command << "\n" << r.output;
    EXPECT_NE(r.output.find(command.starts_with("bench") ? "--work: must not be empty"
                                                         : "--out: must not be empty"),
              std::string::npos)
        << command << "\n"
        << r.output;
  }
  // demo --out naming a file printed the file system's own error.
  testing::WriteText(dir_ / "file", "x\n");
  const Result r = RunSdoslam("demo --out " + (dir_ / "file").string());
  EXPECT_EQ(r.exit_code, 4) << r.output;
  EXPECT_EQ(r.output,
            "error: " + (dir_ / "file").string() + ": --out names a file, not a folder\n");
}

// Ten levels of ten YAML aliases in a --config ran for more than 70 s before failing.
TEST_F(CliRun, AnAliasBombConfigFailsAtOnce) {
  testing::WriteText(dir_ / "bomb.yaml", testing::YamlAliasBomb(10));
  const auto start = std::chrono::steady_clock::now();
  const std::string output = Run((dir_ / "bomb.yaml").string(), (dir_ / "seq").string());
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 2.0);
  EXPECT_EQ(last_.exit_code, 1) << output;
  EXPECT_NE(
      output.find("error: " + (dir_ / "bomb.yaml").string() + ": more than 100000 YAML nodes"),
      std::string::npos)
      << output;
}

// A run's config.yaml alone repeats the run: dataset, frame range and threading are in it.
TEST_F(CliRun, ARunsConfigYamlRerunsItBitIdentically) {
  const std::string first = (dir_ / "first").string(), second = (dir_ / "second").string();
  Result r = RunSdoslam("run --dataset " + (dir_ / "seq").string() + " --config " +
                        (dir_ / "seq" / "camera.yaml").string() +
                        " --sequential --max-frames 20 --out " + first);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = RunSdoslam("run --config " + first + "/config.yaml --out " + second);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("20 frames: 20 tracked"), std::string::npos) << r.output;
  EXPECT_EQ(testing::ReadText(dir_ / "first" / "CameraTrajectory.txt"),
            testing::ReadText(dir_ / "second" / "CameraTrajectory.txt"));
  EXPECT_EQ(testing::ReadText(dir_ / "first" / "config.yaml"),
            testing::ReadText(dir_ / "second" / "config.yaml"));
}

TEST_F(CliRun, MaskScoresNeedACompleteSetWithFeatures) {
  const std::string seq = (dir_ / "seq").string();
  const std::string run = "run --dataset " + seq + " --config " +
                          (dir_ / "seq" / "camera.yaml").string() +
                          " --mode oracle --max-frames 5 --out " + (dir_ / "out").string();
  ASSERT_EQ(RunSdoslam(run).exit_code, 0);
  // No --save-masks: this once printed precision 1.000.
  Result r = RunSdoslam("eval-masks --dataset " + seq + " --run " + (dir_ / "out").string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("run with --save-masks"), std::string::npos) << r.output;
  ASSERT_EQ(RunSdoslam(run + " --save-masks").exit_code, 0);
  r = RunSdoslam("eval-masks --dataset " + seq + " --run " + (dir_ / "out").string() +
                 " --per-frame " + (dir_ / "per_frame.csv").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  // One row per frame and class in view, after the header: none in a static room.
  EXPECT_EQ(testing::ReadText(dir_ / "per_frame.csv"), std::string(kPerFrameScoresHeader) + "\n");
  // A mask changed after the run (or left from another) is not scored.
  const auto mask = std::filesystem::directory_iterator(dir_ / "out" / "masks")->path();
  cv::imwrite(mask.string(), cv::Mat(cv::imread(mask.string()).size(), CV_8U, cv::Scalar(1)));
  r = RunSdoslam("eval-masks --dataset " + seq + " --run " + (dir_ / "out").string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("differs from the result set"), std::string::npos) << r.output;
}

TEST_F(CliRun, AFrontEndOptionInAModeWithoutFrontEndIsAWarning) {
  const Result r =
      RunSdoslam("run --dataset " + (dir_ / "seq").string() + " --config " +
                 (dir_ / "seq" / "camera.yaml").string() +
                 " --detector-model some.onnx --max-frames 3 --out " + (dir_ / "out").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("--detector-model has no effect in mode conventional"), std::string::npos)
      << r.output;
}

// A FIFO, /dev/zero or a folder where a file is read: `vocab info /dev/zero` grew to 4 GB, a FIFO
// hung every command. Each now fails at once, naming the path, exit code 1.
TEST(CliFiles, WhatIsNoRegularFileFailsAtOnce) {
  testing::TempDir dir;
  const std::string fifo = (dir / "fifo").string();
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  testing::WriteText(dir / "gt.txt",
                     "100.0 0 0 0 0 0 0 1\n100.1 1 0 0 0 0 0 1\n100.2 1 1 0 0 0 0 1\n");
  const std::string gt = (dir / "gt.txt").string();
  for (const std::string& path : {fifo, std::string("/dev/zero"), dir.path().string()}) {
    for (const std::string& command :
         {"vocab info " + path, "eval --no-plots --gt " + path + " --est " + gt,
          "eval --no-plots --gt " + gt + " --est " + path,
          "run --dataset " + dir.path().string() + " --config " + path + " --out " +
              (dir / "out").string()}) {
      const auto start = std::chrono::steady_clock::now();
      const Result r = RunSdoslam(command);
      EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
                2.0)
          << command;
      EXPECT_EQ(r.exit_code, 1) << command << "\n" << r.output;
      EXPECT_EQ(r.output, "error: " + path + ": not a regular file\n") << command;
    }
  }
}

// `eval --delta 1e20 --delta-unit frames` reported RTE 0.0000 over 9 pairs (the delta overflowed
// to 0), exit 0. A delta longer than the trajectory gives no RTE (n/a, as for any trajectory too
// short for its delta) and a note naming --delta; the ATE stands.
TEST(CliEvalErrors, ADeltaLongerThanTheTrajectoryGivesNoRteAndSaysWhy) {
  testing::TempDir dir;
  std::string poses;
  for (int k = 0; k < 10; ++k) poses += fmt::format("{}.0 {} 0 0 0 0 0 1\n", 100 + k, k);
  testing::WriteText(dir / "gt.txt", poses);
  const std::string gt = (dir / "gt.txt").string();
  for (const std::string delta : {"1e+20", "20"}) {
    const Result r = RunSdoslam("eval --no-plots --delta " + delta + " --delta-unit frames --gt " +
                                gt + " --est " + gt);
    EXPECT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("n/a        n/a      0\n"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("note: gt: no RTE: RTE delta (--delta) " + delta +
                            " frames: no pose pairs that far apart; the trajectory has 10 poses"),
              std::string::npos)
        << r.output;
  }
}

TEST(CliVocab, BuildsAVocabularyFromImageFoldersAndNamesBadInput) {
  testing::TempDir dir;
  // A TUM-layout sequence (images in rgb/) and a plain folder of images.
  Result r = RunSdoslam("synth --scenario static_room --frames 4 --out " + (dir / "seq").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::filesystem::create_directories(dir / "plain");
  std::filesystem::copy_file(std::filesystem::directory_iterator(dir / "seq" / "rgb")->path(),
                             dir / "plain" / "a.png");
  testing::WriteText(dir / "plain" / "notes.txt", "not an image\n");

  const std::string out = (dir / "v.sdv").string();
  r = RunSdoslam("vocab build --images " + (dir / "seq").string() + " " + (dir / "plain").string() +
                 " --branching 8 --depth 3 --out " + out);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("(branching 8, depth 3) from 5 images"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("descriptors, in"), std::string::npos) << r.output;
  r = RunSdoslam("vocab info " + out);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("branching 8, depth 3"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("trained on 5 images"), std::string::npos) << r.output;
  r = RunSdoslam("vocab build --images " + (dir / "seq").string() + " --max-images 2 --out " + out);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("from 2 images"), std::string::npos) << r.output;

  // The built-in vocabulary is in the executable.
  r = RunSdoslam("vocab info");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("built-in vocabulary: "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("branching 10, depth 4"), std::string::npos) << r.output;

  // Bad input: one message naming the file, exit code 1; usage: exit code 2.
  const std::string missing = (dir / "missing").string();
  r = RunSdoslam("vocab build --images " + missing + " --out " + out);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.output, "error: image folder not found: " + missing + "\n");
  std::filesystem::create_directories(dir / "empty");
  r = RunSdoslam("vocab build --images " + (dir / "empty").string() + " --out " + out);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.output,
            "error: " + (dir / "empty").string() + ": no .png or .jpg images (nor in its rgb/)\n");
  testing::WriteText(dir / "plain" / "b.png", "not a png\n");
  r = RunSdoslam("vocab build --images " + (dir / "plain").string() + " --out " + out);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.output, "error: cannot read image " + (dir / "plain" / "b.png").string() + "\n");
  r = RunSdoslam("vocab info " + (dir / "plain" / "a.png").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("a.png: not an sdoslam vocabulary (bad magic)"), std::string::npos)
      << r.output;
  r = RunSdoslam("vocab build --images " + (dir / "seq").string() + " --branching 1 --out " + out);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("branching must be in 2..255"), std::string::npos) << r.output;
  EXPECT_EQ(RunSdoslam("vocab build --out " + out).exit_code, 2);
  EXPECT_EQ(RunSdoslam("vocab").exit_code, 2);
}

}  // namespace
}  // namespace sdoslam
