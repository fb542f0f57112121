// End-to-end: synthetic dynamic sequences with known ground truth, run in the three modes.
#include "sdoslam/runner/run_on_dataset.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <sstream>
#include <thread>

#include "sdoslam/core/error.h"
#include "sdoslam/eval/metrics.h"
#include "sdoslam/io/omd.h"
#include "sdoslam/io/point_cloud.h"
#include "sdoslam/io/result_set.h"
#include "sdoslam/objects/object_eval.h"
#include "sdoslam/synth/real_background.h"
#include "sdoslam/synth/scenarios.h"
#include "sdoslam/synth/sequence.h"
#include "sdoslam/testing/short_walk.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

constexpr int kFrames = 150;

RunOptions SyntheticRun(const std::filesystem::path& sequence, const std::filesystem::path& out,
                        RunMode mode) {
  RunOptions run;
  run.dataset = sequence;
  run.out = out;
  run.camera = synth::SyntheticCamera();
  run.mode = mode;
  // People are boxes in the renderer: no COCO detector would know them. The detections the
  // renderer writes (tight person boxes) stand in for one: the `file` backend.
  run.front_end.detector = "file";
  run.front_end.detections_file = "detections.json";
  return run;
}

struct ModeResults {
  double conventional = 0, oracle = 0, sdo = 0;
  MaskEvaluation masks;
};

// Renders `frames` frames of a synthetic scenario into dir/seq and returns that folder.
std::filesystem::path WriteScenario(const std::string& scenario, const testing::TempDir& dir,
                                    int frames = kFrames) {
  synth::SynthOptions options;
  options.scenario = scenario;
  options.frames = frames;
  const auto sequence = dir / "seq";
  synth::WriteSequence(options, sequence, /*overwrite=*/true);
  return sequence;
}

// The colour images of a sequence written by WriteShortWalk, in frame order.
std::vector<std::filesystem::path> ColourImages(const std::filesystem::path& sequence) {
  std::vector<std::filesystem::path> rgb;
  for (const auto& e : std::filesystem::directory_iterator(sequence / "rgb"))
    rgb.push_back(e.path());
  std::sort(rgb.begin(), rgb.end());
  return rgb;
}

// Runs `modes` on a rendered sequence and records each one's ATE (and sdo's masks) in `r`.
void RunModes(const std::filesystem::path& sequence, const testing::TempDir& dir,
              const std::vector<RunMode>& modes, ModeResults* r) {
  for (RunMode mode : modes) {
    const RunSummary s = RunOnDataset(SyntheticRun(sequence, dir / ToString(mode), mode));
    EXPECT_TRUE(s.evaluation.has_value());
    EXPECT_GE(s.tracked, kFrames - 5u) << ToString(mode);
    const double ate = s.evaluation ? s.evaluation->ate.translation.rmse : 1e9;
    (mode == RunMode::kConventional ? r->conventional
     : mode == RunMode::kOracle     ? r->oracle
                                    : r->sdo) = ate;
    if (mode == RunMode::kSdo) {
      EXPECT_TRUE(s.masks.has_value());
      if (s.masks) r->masks = *s.masks;
    }
  }
}

// The targets: sdo within 1.5 × oracle + 5 mm; at least 3× better than conventional
// where conventional exceeds 3 cm; mask IoU ≥ 0.7 for people and ≥ 0.6 for unknown objects, for
// each class the sequence has.
void ExpectTheScenarioBars(const std::string& scenario, const ModeResults& r) {
  std::cout << scenario << ": ATE conventional " << r.conventional << " oracle " << r.oracle
            << " sdo " << r.sdo << '\n'
            << FormatMaskEvaluation(r.masks, scenario);
  EXPECT_LE(r.sdo, 1.5 * r.oracle + 0.005);
  if (r.conventional > 0.03) {
    EXPECT_LE(3.0 * r.sdo, r.conventional);
  }
  ASSERT_FALSE(r.masks.per_class.empty());
  if (r.masks.per_class.count("person")) {
    EXPECT_GE(r.masks.per_class.at("person").Iou(), 0.7);
  }
  if (r.masks.per_class.count("unknown")) {
    EXPECT_GE(r.masks.per_class.at("unknown").Iou(), 0.6);
  }
}

class DynamicScenario : public ::testing::TestWithParam<std::string> {};

TEST_P(DynamicScenario, SdoApproachesTheOracleAndBeatsConventional) {
  testing::TempDir dir;
  const auto sequence = WriteScenario(GetParam(), dir);
  ModeResults r;
  RunModes(sequence, dir, {RunMode::kConventional, RunMode::kOracle, RunMode::kSdo}, &r);
  ExpectTheScenarioBars(GetParam(), r);
}

// Unknown boxes (and, in `mixed`, a box carried with the camera and a person; in box_alongside a
// box moving with the camera, in parked_cart one that stands still, then moves). The front end
// alone reached 20–25 mm on the first two (84 mm and 90 lost frames on mixed, 23 mm on
// box_alongside); with the scene-flow consistency check (issue 6) sdo meets the bars: measured
// 6.6–10.3 mm against oracles of 3.8–7.4 mm, box mask IoU 0.67–0.70 (0.24–0.50 from the front
// end's pixels alone).
// box_alongside and parked_cart are held to the same bars by the ConsistencyCheck tests below,
// which render them once for both; boxes_unconstrained is in Extended/.

INSTANTIATE_TEST_SUITE_P(People, DynamicScenario, ::testing::Values("walking_xyz", "walking_rpy"));

// The same bar where other tests already hold it: a still camera; the boxes under translation
// only, a part of boxes_unconstrained's motion; mixed, whose person, swinging box and carried
// box PipelineRealBackground runs over real frames against a stricter bar; walking_halfsphere,
// whose camera both translates and turns as walking_xyz and walking_rpy do; loop, people on a
// walk around the room, which LongRun (450 frames) and PipelineLoopClosing (700) make longer;
// and boxes_unconstrained, unknown boxes that PipelineRealBackground (swinging, carried and
// pushed boxes over real frames, stricter bars) and the ConsistencyCheck tests hold. Half a
// minute of CI each, so scripts/test.sh leaves the Extended/ tests out (CI stays within 20
// minutes on 2 cores); scripts/test.sh --extended runs them.
INSTANTIATE_TEST_SUITE_P(Extended, DynamicScenario,
                         ::testing::Values("walking_static", "boxes_translational", "mixed",
                                           "walking_halfsphere", "loop", "boxes_unconstrained"));

// Issue 6: a box carried alongside the camera so that its image motion matches the background's:
// its outline has no flow gradient and the front end misses it. The scene-flow consistency check
// must catch it: more of its features found dynamic, a better trajectory, and in every frame the
// static set reaches a fixed point within the iteration limit. With the check, sdo meets the
// scenario bars of DynamicScenario against conventional and the oracle.
TEST(ConsistencyCheck, CatchesAnObjectThatLeavesNoFlowBoundary) {
  testing::TempDir dir;
  const auto sequence = WriteScenario("box_alongside", dir);
  struct Outcome {
    double ate = 1e9;
    MaskEvaluation masks;
    int checked = 0, converged = 0, reverted = 0, max_iterations = 0;
  };
  auto run_with = [&](bool check) {
    RunOptions run = SyntheticRun(sequence, dir / (check ? "on" : "off"), RunMode::kSdo);
    run.slam.tracking.consistency.enabled = check;
    Outcome o;
    run.after_frame = [&](const TrackingResult& r, const System&) {
      if (r.check_iterations == 0) return;
      ++o.checked;
      o.converged += r.check_converged;
      o.reverted += r.check_reverted;
      o.max_iterations = std::max(o.max_iterations, r.check_iterations);
    };
    const RunSummary s = RunOnDataset(run);
    EXPECT_EQ(s.tracked, static_cast<size_t>(kFrames));
    if (s.evaluation) o.ate = s.evaluation->ate.translation.rmse;
    if (s.masks) o.masks = *s.masks;
    return o;
  };
  const Outcome off = run_with(false), on = run_with(true);
  std::cout << "box_alongside: ATE without the check " << off.ate << ", with " << on.ate
            << "; feature recall " << off.masks.features.Recall() << " -> "
            << on.masks.features.Recall() << "; checked " << on.checked << " frames, converged "
            << on.converged << ", at most " << on.max_iterations << " rounds\n";
  EXPECT_EQ(off.checked, 0);
  // Measured: recall 0.00 -> 0.66, ATE 23 -> 10 mm (oracle 4.5 mm).
  EXPECT_GE(on.masks.features.Recall(), off.masks.features.Recall() + 0.4);
  EXPECT_LE(on.ate, off.ate);
  EXPECT_LE(on.ate, 0.7 * off.ate);
  EXPECT_GE(on.checked, kFrames - 10);
  EXPECT_EQ(on.converged + on.reverted, on.checked);
  EXPECT_EQ(on.reverted, 0);
  ModeResults r;
  r.sdo = on.ate;
  r.masks = on.masks;
  RunModes(sequence, dir, {RunMode::kConventional, RunMode::kOracle}, &r);
  ExpectTheScenarioBars("box_alongside", r);
}

// Issue 6: a cart parked for two seconds, then pushed away. While parked it is static scene and
// gets mapped; once it moves, the consistency check and the free-space test must take its
// landmarks out of the map. With the check off they stay, which shows what removes them. With
// the check, sdo meets the scenario bars of DynamicScenario against conventional and the oracle.
TEST(ConsistencyCheck, LandmarksOfAParkedCartLeaveTheMapOnceItMoves) {
  testing::TempDir dir;
  const auto sequence = WriteScenario("parked_cart", dir);
  const double duration = (kFrames - 1) / synth::SyntheticCamera().fps;
  const synth::Scenario scenario = synth::MakeScenario("parked_cart", duration);
  const synth::SceneObject& cart = scenario.scene.objects.at(0);
  // The map's world is the first camera's frame.
  const Eigen::Isometry3d T_world_map = synth::CameraPoseAt(scenario.motion, 0, duration);
  const Eigen::Isometry3d T_cart_world = cart.pose_at(0).inverse();
  const Eigen::Vector3d half = cart.parts_at(0).at(0).half_size;
  // Landmarks within 5 cm of where the cart was parked, the floor under it excluded.
  auto on_parked_place = [&](const Map& map) {
    int count = 0;
    for (const auto& [id, p] : map.points()) {
      if (p->bad) continue;
      const Eigen::Vector3d x = T_cart_world * T_world_map * p->position;
      count += std::abs(x.x()) <= half.x() + 0.05 && std::abs(x.y()) <= half.y() + 0.05 &&
               x.z() >= -half.z() + 0.04 && x.z() <= half.z() + 0.05;
    }
    return count;
  };
  struct Counts {
    int parked = 0, end = 0;
    size_t map_points = 0;
    double ate = 1e9;
    MaskEvaluation masks;
  };
  auto run_with = [&](bool check) {
    RunOptions run = SyntheticRun(sequence, dir / (check ? "on" : "off"), RunMode::kSdo);
    run.slam.tracking.consistency.enabled = check;
    Counts c;
    run.after_frame = [&](const TrackingResult& r, const System& slam) {
      if (r.index == 55) c.parked = on_parked_place(slam.map());  // t = 1.83 s; moves at 2 s
      if (r.index + 1 == kFrames) c.end = on_parked_place(slam.map());
    };
    const RunSummary s = RunOnDataset(run);
    EXPECT_GE(s.tracked, kFrames - 5u);
    c.map_points = s.map_points;
    if (s.evaluation) c.ate = s.evaluation->ate.translation.rmse;
    if (s.masks) c.masks = *s.masks;
    return c;
  };
  const Counts off = run_with(false), on = run_with(true);
  std::cout << "parked_cart: landmarks on the parking place while parked / at the end: check off "
            << off.parked << " / " << off.end << ", on " << on.parked << " / " << on.end
            << "; map points at the end " << off.map_points << " / " << on.map_points << '\n';
  EXPECT_GE(on.parked, 20);
  EXPECT_LE(on.end, on.parked / 10);
  EXPECT_GE(off.end, off.parked / 4);  // measured: 42 of 85 stay
  // Hygiene removes what moved, not the room.
  EXPECT_GE(on.map_points, off.map_points / 2);
  ModeResults r;
  r.sdo = on.ate;
  r.masks = on.masks;
  RunModes(sequence, dir, {RunMode::kConventional, RunMode::kOracle}, &r);
  ExpectTheScenarioBars("parked_cart", r);
}

// Long runs: 450 frames of people walking through the room, the dynamic front end on, with
// local mapping inline and in its thread (mapping.concurrent). Frame poses are stored relative to
// keyframes that culling later removes: they must stay as good as the keyframes themselves, and a
// camera that never leaves the room must keep a map of bounded size. One test renders the sequence
// once for both modes (ctest runs each test in a process of its own: two tests would render it
// twice).
TEST(LongRun, FramePosesStayWithTheirKeyFramesAndTheMapStaysBoundedInlineAndThreaded) {
  testing::TempDir dir;
  WriteScenario("walking_xyz", dir, 450);
  for (const bool sequential : {true, false}) {
    SCOPED_TRACE(sequential ? "sequential" : "threaded");
    RunOptions run =
        SyntheticRun(dir / "seq", dir / (sequential ? "seq_out" : "thr_out"), RunMode::kSdo);
    run.slam.sequential = sequential;
    run.slam.mapping.concurrent = !sequential;
    size_t most_keyframes = 0;
    run.after_frame = [&](const TrackingResult& r, const System&) {
      most_keyframes = std::max(most_keyframes, r.keyframes_alive);
    };
    const RunSummary s = RunOnDataset(run);
    ASSERT_EQ(s.tracked, 450u);
    ASSERT_TRUE(s.evaluation && s.keyframe_evaluation);
    const double frame_ate = s.evaluation->ate.translation.rmse;
    const double keyframe_ate = s.keyframe_evaluation->ate.translation.rmse;
    std::cout << (sequential ? "sequential" : "threaded") << ": frame ATE " << frame_ate
              << " keyframe ATE " << keyframe_ate << " max " << s.evaluation->ate.translation.max
              << " keyframes made " << s.mapping.size() << " alive at most " << most_keyframes
              << '\n';
    EXPECT_LE(frame_ate, 1.5 * keyframe_ate + 0.002);
    EXPECT_LE(frame_ate, 0.010);
    // Under the frames' alignment the keyframes are the frames at their times: no better than
    // aligned on their own (the least-squares optimum for them).
    ASSERT_TRUE(s.keyframe_ate_in_frame_alignment);
    EXPECT_EQ(s.keyframe_ate_in_frame_alignment->translation.count, s.keyframe_trajectory.size());
    EXPECT_GE(s.keyframe_ate_in_frame_alignment->translation.rmse, keyframe_ate);
    EXPECT_LE(s.evaluation->ate.translation.max, 0.05) << "a frame more than 5 cm off";
    // About one keyframe in seven frames is made; culling keeps those alive to the place.
    EXPECT_GE(s.mapping.size(), 40u);
    EXPECT_LE(most_keyframes, 35u);
    // Each keyframe's mapping CPU time is measured on the thread that mapped it: some work, and
    // no more than its wall time.
    for (const MappingRecord& m : s.mapping) {
      EXPECT_GT(m.cpu_ms, 0.0) << m.frame_index;
      EXPECT_LE(m.cpu_ms, m.ms + 1.0) << m.frame_index;
    }
  }
}

// Conventional SLAM takes walking people for the room: each keyframe holds points on them
// that one or two keyframes ever see, and ORB-SLAM2's redundancy rule, which counts every point,
// found few keyframes redundant (1,000 frames: 340 alive and growing). Past their probation such
// points no longer keep a keyframe (mapping.transient_observations). The crowd quota, which would
// bound both, is off here, and so is the spacing of keyframes (tracking.
// min_frames_between_keyframes), which makes fewer of them (32 alive against 26 with it).
TEST(LongRun, ConventionalKeyFramesAreNotKeptByPointsOnPeople) {
  testing::TempDir dir;
  WriteScenario("walking_xyz", dir, 100);
  std::map<int, size_t> alive;
  for (const int transient : {0, 2}) {
    RunOptions run =
        SyntheticRun(dir / "seq", dir / ("t" + std::to_string(transient)), RunMode::kConventional);
    run.slam.sequential = true;
    run.slam.mapping.transient_observations = transient;
    run.slam.mapping.crowded_distance = 0;
    run.slam.tracking.min_frames_between_keyframes = 0;
    const RunSummary s = RunOnDataset(run);
    ASSERT_EQ(s.tracked, 100u);
    alive[transient] = s.keyframes;
  }
  std::cout << "keyframes alive, counting every point: " << alive[0]
            << "; not those of one or two keyframes: " << alive[2] << '\n';
  EXPECT_LE(alive[2] * 3, alive[0] * 2);  // measured: 28 against 50
}

// People walk through the long loop (synth long_loop_people: once around the room, then its
// first metres again), and the front end runs (`sdo`). Without loop closing the ATE is 121 mm;
// with it the revisit is recognised on static points only (the people's features carry dynamic
// labels and never vote) and the ATE falls to 22 mm (measured 2026-11-27, with the walk made
// 700 frames long). The run without closing is not repeated here (it is the suite's costliest
// run): the bar, 30 mm, is a quarter of its measured ATE, and SlamLoopClosing shows on the same
// path that without closing the drift stays above 30 mm.
TEST(PipelineLoopClosing, PeopleWalkingThroughTheLoopDoNotStopItClosing) {
  testing::TempDir dir;
  WriteScenario("long_loop_people", dir, synth::kLongLoopFrames);
  RunOptions run = SyntheticRun(dir / "seq", dir / "with", RunMode::kSdo);
  // The default detector (HOG), as a user runs it. (With the renderer's person boxes instead the
  // front end leaves a different map: 31 mm with closing against 59 mm without, 0.52x.)
  run.front_end = FrontEndOptions{};
  const RunSummary with = RunOnDataset(run);
  ASSERT_TRUE(with.evaluation);
  const double ate_with = with.evaluation->ate.translation.rmse;
  std::cout << "long loop with people, sdo: ATE with closing " << ate_with
            << " (121 mm without), loops " << with.loops.size() << '\n';
  EXPECT_EQ(with.tracked, static_cast<size_t>(synth::kLongLoopFrames));
  ASSERT_EQ(with.loops.size(), 1u);
  EXPECT_GE(with.loops[0].frame_index, static_cast<size_t>(synth::kLongLoopFrames) * 4 / 5);
  EXPECT_LE(with.loops[0].loop_frame_index, static_cast<size_t>(synth::kLongLoopFrames) / 5);
  EXPECT_LE(ate_with, 0.030);
  // loops.csv holds it for the user.
  const std::string log = testing::ReadText(dir / "with" / "loops.csv");
  EXPECT_NE(log.find(std::to_string(with.loops[0].frame_index) + "," +
                     std::to_string(with.loops[0].loop_frame_index) + ","),
            std::string::npos)
      << log;
  EXPECT_NE(log.find(",run\n"), std::string::npos) << "the global BA ran: " << log;
}

// The shared real desk clip (tum_fr2_desk_50) with its camera; the folder may be absent.
RunOptions RealDeskRun() {
  RunOptions run;
  run.dataset = testing::SharedDir() / "data" / "tum_fr2_desk_50";
  run.camera = LoadCameraConfig(testing::SourceDir() / "configs" / "tum_fr2.yaml");
  return run;
}

TEST(Pipeline, SdoOnTheRealStaticDeskIsAsGoodAsConventional) {
  RunOptions run = RealDeskRun();
  if (!std::filesystem::is_directory(run.dataset)) GTEST_SKIP() << run.dataset << " absent";
  testing::TempDir dir;
  double ate[2];
  for (RunMode mode : {RunMode::kConventional, RunMode::kSdo}) {
    run.mode = mode;
    run.out = dir / ToString(mode);
    const RunSummary s = RunOnDataset(run);  // default backends: rgbd, hog, dis
    ASSERT_TRUE(s.evaluation.has_value());
    ate[mode == RunMode::kSdo] = s.evaluation->ate.translation.rmse;
  }
  EXPECT_LE(ate[1], 1.1 * ate[0]) << "conventional " << ate[0] << " sdo " << ate[1];
}

// Real hand-held footage turning fast with blur (TUM fr1_rpy, 300 frames; ORB-SLAM2 25.1-27.6
// mm), with configs/tum_fr1.yaml, sequential. Both modes: every frame tracked, ATE under what
// each mode gets at its worst over 20 ORB feature counts
// (960-1055): conventional 7.4-9.9 mm (median 8.6), sdo 7.7-11.5 (median 9.3). Without the
// rolling-shutter compensation (camera.readout_s: 0) conventional is at 23.2 mm (median) and
// fails; with readout_s 0 and depth factor 5000, 24.9. With the rows moved by the motion model
// alone (tracking.rolling_shutter_refit: false) conventional was at 8.5-11.1 (median 10.1) and sdo
// at 9.5-12.3 (median 10.6). Conventional: the keyframes alone within it too, and the keyframes the
// view needs as it turns away. With ORB-SLAM2's 100 close points the keyframes came 10-20 frames
// apart (26 made) and the map fell behind the view: 35 mm; with the 1x local-map window, 62 mm.
TEST(Pipeline, FastRotationOnRealFootageStaysAccurate) {
  const auto data = testing::SharedDir() / "data" / "tum_fr1_rpy_300";
  if (!std::filesystem::is_directory(data)) GTEST_SKIP() << data << " absent";
  testing::TempDir dir;
  RunOptions run = LoadRunConfig(testing::SourceDir() / "configs" / "tum_fr1.yaml");
  run.dataset = data;
  run.slam.sequential = true;
  double ate[2];
  for (RunMode mode : {RunMode::kConventional, RunMode::kSdo}) {
    run.mode = mode;
    run.out = dir / ToString(mode);
    const RunSummary s = RunOnDataset(run);
    ASSERT_TRUE(s.evaluation.has_value());
    ASSERT_TRUE(s.keyframe_evaluation.has_value());
    EXPECT_EQ(s.tracked, 300u) << ToString(mode);
    // No loop needs closing (none is, over the 20 counts). Before the rolling shutter was
    // compensated, the loop back to the start within the first 4 s carried the run (odometry
    // alone: 37-43 mm).
    ate[mode == RunMode::kSdo] = s.evaluation->ate.translation.rmse;
    std::cout << "fr1_rpy_300 " << ToString(mode) << ": ATE " << ate[mode == RunMode::kSdo]
              << ", keyframes " << s.keyframe_evaluation->ate.translation.rmse << ", "
              << s.mapping.size() << " keyframes made\n";
    if (mode == RunMode::kConventional) {
      // Over the 20 counts: keyframes 9.5-13.8 mm, 41-50 made.
      EXPECT_LE(s.keyframe_evaluation->ate.translation.rmse, 0.018);
      EXPECT_GE(s.mapping.size(), 35u);
    }
  }
  EXPECT_LE(ate[0], 0.011);
  EXPECT_LE(ate[1], 0.0125);
}

// How a run's map.ply agrees with the images: each point is projected into the frames given
// (every tracked frame's estimated pose from the run's CameraTrajectory.txt) where it lands on
// valid depth; it agrees there when its depth is within 4 cm + 3 % of the measured one.
struct CloudAgreement {
  size_t points = 0;
  size_t checked = 0;              // (point, frame) pairs on valid depth
  size_t agree = 0;                // ... whose depth agrees
  double median_colour_error = 0;  // mean |rgb - image| over the channels, agreeing pairs
  // The same with each pixel compared to the colour of another point (the next in the file):
  // what the error is when colours carry no information.
  double median_colour_error_shuffled = 0;
  size_t on_movers = 0;  // points that agree with some frame's depth inside its dynamic mask
  size_t grey = 0;       // points whose three channels are equal
};

CloudAgreement CheckCloud(const std::filesystem::path& run_out, const RgbdDataset& dataset,
                          const std::vector<size_t>& frames, bool with_masks) {
  const std::vector<ColoredPoint> cloud = ReadPly(run_out / "map.ply");
  const Trajectory estimate = ReadTumTrajectory(run_out / "CameraTrajectory.txt");
  const Camera camera(dataset.camera());
  CloudAgreement a;
  a.points = cloud.size();
  for (const ColoredPoint& p : cloud) a.grey += p.rgb[0] == p.rgb[1] && p.rgb[1] == p.rgb[2];
  std::vector<double> colour_errors, shuffled_errors;
  const auto colour_error = [](const ColoredPoint& p, const cv::Vec3b& bgr) {
    return (std::abs(p.rgb[0] - bgr[2]) + std::abs(p.rgb[1] - bgr[1]) +
            std::abs(p.rgb[2] - bgr[0])) /
           3.0;
  };
  std::vector<bool> on_mover(cloud.size(), false);
  for (size_t k : frames) {
    const RgbdFrame frame = dataset.Load(k);
    const auto pose = InterpolatePose(estimate, frame.timestamp, 1e-6);
    if (!pose) continue;
    cv::Mat mask;
    if (with_masks) {
      const auto path = dataset.folder() / "dynamic" / dataset.entries()[k].rgb_path.filename();
      mask = cv::imread(path.string(), cv::IMREAD_GRAYSCALE);
      EXPECT_FALSE(mask.empty()) << path;
    }
    const Eigen::Isometry3d T_camera_world = pose->inverse();
    for (size_t i = 0; i < cloud.size(); ++i) {
      const Eigen::Vector3d X = T_camera_world * cloud[i].position.cast<double>();
      if (X.z() <= 0.1) continue;
      const Eigen::Vector2d uv = camera.Distort(camera.Project(X));
      const int u = static_cast<int>(std::lround(uv.x())),
                v = static_cast<int>(std::lround(uv.y()));
      if (u < 0 || v < 0 || u >= frame.depth.cols || v >= frame.depth.rows) continue;
      const float measured = frame.depth.at<float>(v, u);
      if (measured <= 0) continue;
      ++a.checked;
      if (std::abs(X.z() - measured) > 0.04 + 0.03 * measured) continue;
      ++a.agree;
      const cv::Vec3b bgr = frame.bgr.at<cv::Vec3b>(v, u);
      colour_errors.push_back(colour_error(cloud[i], bgr));
      shuffled_errors.push_back(colour_error(cloud[(i + 1) % cloud.size()], bgr));
      if (!mask.empty() && mask.at<uint8_t>(v, u) != 0) on_mover[i] = true;
    }
  }
  a.on_movers = static_cast<size_t>(std::count(on_mover.begin(), on_mover.end(), true));
  const auto median = [](std::vector<double> v) {
    if (v.empty()) return 0.0;
    std::nth_element(v.begin(), v.begin() + static_cast<ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  a.median_colour_error = median(colour_errors);
  a.median_colour_error_shuffled = median(shuffled_errors);
  return a;
}

// --save-map on the real desk: the cloud lies on the surfaces the frames see (depth agrees
// where a point is in view) and carries their colours.
TEST(PipelineMap, TheStaticMapLiesOnTheRealDeskWithItsColours) {
  RunOptions run = RealDeskRun();
  const auto& data = run.dataset;
  if (!std::filesystem::is_directory(data)) GTEST_SKIP() << data << " absent";
  testing::TempDir dir;
  run.slam.sequential = true;
  run.save_map = true;
  run.out = dir / "out";
  const RunSummary s = RunOnDataset(run);
  const RgbdDataset dataset(data, run.camera);
  const CloudAgreement a = CheckCloud(run.out, dataset, {0, 10, 20, 30, 40, 49}, false);
  std::cout << "map.ply: " << a.points << " points; " << a.agree << " of " << a.checked
            << " in-view depths agree; median colour error " << a.median_colour_error
            << " (another point's colour: " << a.median_colour_error_shuffled << "); " << a.grey
            << " grey; map points " << s.map_points << '\n';
  EXPECT_EQ(a.points, s.map_cloud_points);
  // Points one keyframe made and none confirmed are left out (measured: 454 of 963).
  EXPECT_GE(a.points, 300u);
  EXPECT_LT(a.points, s.map_points);
  // Points hidden behind nearer surfaces disagree; most do not (measured: 85 %).
  EXPECT_GE(static_cast<double>(a.agree), 0.75 * static_cast<double>(a.checked));
  // Colours are sampled at corners, where they change fastest (measured: 15 against 63).
  EXPECT_LE(a.median_colour_error, 0.5 * a.median_colour_error_shuffled);
  // In colour: a grey image's value in all three channels passes the test above on this
  // greyish desk, and was what the map got while extraction was handed the grey image (measured
  // then: 454 of 454 points grey, median colour error 22; now none).
  EXPECT_LT(static_cast<double>(a.grey), 0.1 * static_cast<double>(a.points)) << a.grey;
}

// Points on people never reach the map when their features are labelled dynamic (oracle: the
// renderer's masks), and do in conventional mode: the count of points that lie on a person in
// some frame (depth agrees inside the frame's dynamic mask).
TEST(PipelineMap, PointsOnPeopleStayOutOfTheStaticMap) {
  testing::TempDir dir;
  const auto sequence = WriteScenario("walking_xyz", dir);
  std::vector<size_t> frames;
  for (size_t k = 0; k < kFrames; k += 5) frames.push_back(k);
  size_t on_people[2] = {0, 0}, points[2] = {0, 0};
  for (RunMode mode : {RunMode::kConventional, RunMode::kOracle}) {
    RunOptions run = SyntheticRun(sequence, dir / ToString(mode), mode);
    run.slam.sequential = true;
    run.save_map = true;
    RunOnDataset(run);
    const RgbdDataset dataset(sequence, run.camera);
    const CloudAgreement a = CheckCloud(run.out, dataset, frames, true);
    const bool oracle = mode == RunMode::kOracle;
    on_people[oracle] = a.on_movers;
    points[oracle] = a.points;
    std::cout << ToString(mode) << ": " << a.points << " points, " << a.on_movers << " on people; "
              << a.agree << " of " << a.checked << " depths agree\n";
  }
  EXPECT_GE(on_people[0], 50u);
  // The count also takes static points that a person's surface touches in some frame (the floor
  // under a foot, the wall beside a shoulder): about 1 % of the oracle's map (measured 9 of
  // 1,070 points; 11 of 1,044 once keyframes were no longer kept by transient points).
  EXPECT_LE(on_people[1], points[1] / 50);
  EXPECT_LE(10 * on_people[1], on_people[0]);
}

TEST(Pipeline, NanoDetRunsInsideThePipeline) {
  RunOptions run = RealDeskRun();
  const auto model = testing::SharedDir() / "models" / "nanodet-m-320" / "nanodet-m-320.onnx";
  if (!std::filesystem::is_directory(run.dataset) || !std::filesystem::exists(model))
    GTEST_SKIP() << "../shared data or models absent";
  testing::TempDir dir;
  run.mode = RunMode::kSdo;
  run.front_end.detector = "nanodet";
  run.front_end.detector_model = model;
  run.out = dir / "sdo";
  run.save_overlays = true;
  const RunSummary s = RunOnDataset(run);
  ASSERT_TRUE(s.evaluation.has_value());
  EXPECT_LT(s.evaluation->ate.translation.rmse, 0.012);
  EXPECT_EQ(s.tracked, 50u);
  // The overlay of the first frame shows the detector's yellow boxes (tv, keyboard, ...).
  const cv::Mat overlay = cv::imread((dir / "sdo" / "overlays" / "1311868164.363181.png").string());
  ASSERT_FALSE(overlay.empty());
  EXPECT_GT(cv::countNonZero(cv::Mat(overlay == cv::Scalar(0, 255, 255)).reshape(1)), 0);
}

// Bad inputs fail before the first frame, and no result file is written.
TEST(Pipeline, BadFrontEndInputsFailBeforeTheRun) {
  testing::TempDir dir;
  synth::SynthOptions options;
  options.scenario = "walking_static";
  options.frames = 3;
  const auto sequence = dir / "seq";
  synth::WriteSequence(options, sequence, true);
  auto expect_error = [&](RunOptions run, const std::string& fragment) {
    run.out = dir / "out";
    try {
      RunOnDataset(run);
      ADD_FAILURE() << "no error for " << fragment;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
    EXPECT_FALSE(std::filesystem::exists(dir / "out" / "CameraTrajectory.txt"));
  };
  RunOptions run = SyntheticRun(sequence, dir / "out", RunMode::kSdo);
  run.front_end.detector = "nanodet";
  run.front_end.detector_model = dir / "missing.onnx";
  expect_error(run, "missing.onnx: model file for 'nanodet' does not exist");

  run = SyntheticRun(sequence, dir / "out", RunMode::kSdo);
  run.front_end.segmenter = "file";
  run.front_end.masks_folder = "masks";  // relative to the dataset
  std::filesystem::create_directories(sequence / "masks");
  for (const auto& e : std::filesystem::directory_iterator(sequence / "rgb")) {
    cv::imwrite((sequence / "masks" / e.path().filename()).string(),
                cv::Mat(240, 320, CV_8U, cv::Scalar(1)));
  }
  expect_error(run, "instance mask is 320x240, the images are 640x480");

  run = SyntheticRun(sequence, dir / "out", RunMode::kSdo);
  run.front_end.flow = "pwc";
  expect_error(run, "unknown flow backend 'pwc'");

  std::filesystem::remove_all(sequence / "dynamic");
  expect_error(SyntheticRun(sequence, dir / "out", RunMode::kOracle),
               "oracle mode needs the ground-truth dynamic masks");
}

}  // namespace
}  // namespace sdoslam

namespace sdoslam {
namespace {

// People no detector knows (the renderer's are boxes, and no detector runs here) are found by
// motion alone: the motion-boundary test and the scene-flow check. Most features on a walking
// person cannot be followed back five frames by Lucas–Kanade (the body turns and occludes), so
// the check could not judge them, they stayed static and single frames went 3-5 cm off
// (250 frames: 9.1 mm, worst frame 50 mm). Retried over two frames they are judged: close to
// the ground-truth masks, and no frame far off.
TEST(PipelineMotionOnly, PeopleNoDetectorKnowsAreTakenOutByTheirMotion) {
  testing::TempDir dir;
  WriteScenario("walking_xyz", dir, 250);
  RunOptions run = SyntheticRun(dir / "seq", dir / "oracle", RunMode::kOracle);
  run.front_end.detector = "none";
  run.slam.sequential = true;
  const RunSummary oracle = RunOnDataset(run);
  run.mode = RunMode::kSdo;
  run.out = dir / "sdo";
  const RunSummary sdo = RunOnDataset(run);
  ASSERT_TRUE(oracle.evaluation && sdo.evaluation);
  EXPECT_EQ(sdo.tracked, 250u);
  const double bar = 1.15 * oracle.evaluation->ate.translation.rmse + 0.001;
  EXPECT_LE(sdo.evaluation->ate.translation.rmse, bar)
      << "oracle " << oracle.evaluation->ate.translation.rmse;
  EXPECT_LE(sdo.evaluation->ate.translation.max, 0.03) << "a frame more than 3 cm off";
}

// Issue 15: boxes swinging through the real desk recording, played forward and back (99 real
// frames, real trajectory). The scene-flow check must take them out: without it the boxes drag
// the pose (sdo without the check 50 mm, conventional 65 mm; with it 9.5 mm, oracle 5.1 mm).
struct RealBackgroundResult {
  std::map<RunMode, double> ate;
  std::map<RunMode, size_t> tracked;
  MaskEvaluation sdo_masks;
};

// `scenario` rendered into the real desk clip played forward and back (99 frames), written to
// dir/seq; returns the options it was written with (camera included), or nullopt when the
// shared data is absent.
std::optional<synth::BackgroundSynthOptions> WriteDeskPlay(const std::string& scenario,
                                                           const testing::TempDir& dir,
                                                           uint32_t seed = 1) {
  const auto desk = testing::SharedDir() / "data" / "tum_fr2_desk_50";
  if (!std::filesystem::is_directory(desk)) return std::nullopt;
  synth::BackgroundSynthOptions options;
  options.background = desk;
  options.camera = LoadCameraConfig(testing::SourceDir() / "configs" / "tum_fr2.yaml");
  options.scenario = scenario;
  options.forward_backward = true;
  options.seed = seed;
  synth::WriteBackgroundSequence(options, dir / "seq");
  return options;
}

std::optional<RealBackgroundResult> RunOverTheRealDesk(const std::string& scenario,
                                                       const std::vector<RunMode>& modes,
                                                       uint32_t seed = 1) {
  testing::TempDir dir;
  const auto written = WriteDeskPlay(scenario, dir, seed);
  if (!written) return std::nullopt;
  const synth::BackgroundSynthOptions& options = *written;
  RunOptions run;
  run.dataset = dir / "seq";
  run.camera = options.camera;
  run.slam.sequential = true;
  RealBackgroundResult result;
  for (RunMode mode : modes) {
    run.mode = mode;
    run.out = dir / ToString(mode);
    const RunSummary s = RunOnDataset(run);
    EXPECT_TRUE(s.evaluation.has_value());
    result.ate[mode] = s.evaluation ? s.evaluation->ate.translation.rmse : 1e9;
    result.tracked[mode] = s.tracked;
    if (mode == RunMode::kSdo && s.masks) result.sdo_masks = *s.masks;
  }
  return result;
}

// The bar on a real-background sequence: every frame tracked, sdo within
// 1.3 x oracle + 2 mm, and the unknown objects' masks at IoU >= 0.6.
void ExpectTheOracleBarAndUnknownMasks(const std::string& scenario, uint32_t seed = 1) {
  const auto r = RunOverTheRealDesk(scenario, {RunMode::kOracle, RunMode::kSdo}, seed);
  if (!r) GTEST_SKIP() << "tum_fr2_desk_50 absent";
  EXPECT_EQ(r->tracked.at(RunMode::kSdo), 99u);
  const double sdo = r->ate.at(RunMode::kSdo), oracle = r->ate.at(RunMode::kOracle);
  EXPECT_LE(sdo, 1.3 * oracle + 0.002) << "sdo " << sdo << " oracle " << oracle;
  ASSERT_EQ(r->sdo_masks.per_class.count("unknown"), 1u);
  EXPECT_GE(r->sdo_masks.per_class.at("unknown").Iou(), 0.6);
}

TEST(PipelineRealBackground, SwingingBoxesOverTheRealDeskAreTakenOut) {
  const auto r = RunOverTheRealDesk("swinging_boxes",
                                    {RunMode::kConventional, RunMode::kOracle, RunMode::kSdo});
  if (!r) GTEST_SKIP() << "tum_fr2_desk_50 absent";
  EXPECT_EQ(r->tracked.at(RunMode::kSdo), 99u);
  const double sdo = r->ate.at(RunMode::kSdo), oracle = r->ate.at(RunMode::kOracle);
  EXPECT_LE(sdo, 1.3 * oracle + 0.002) << "sdo " << sdo << " oracle " << oracle;
  EXPECT_LT(sdo, 0.3 * r->ate.at(RunMode::kConventional));
}

// A large textured box carried in front of the camera (26 % of the image, more corners than the
// desk): most features are on it, and before the static world was chosen by area, tracking
// followed the box (102 mm against the oracle's 4.1). Held on three noise seeds, each to the
// bar: while the check judged a segment above 20 % of the image feature by feature, seed 2 gave
// 7.1 mm against a bar of 6.9 (the features left unmeasured on the box stayed static in the
// frames the front end missed it).
TEST(PipelineRealBackground, ABoxCarriedWithTheCameraDoesNotCaptureThePose) {
  for (uint32_t seed : {1u, 2u, 3u}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    ExpectTheOracleBarAndUnknownMasks("carried_box", seed);
  }
}

// A crate stands still on the desk for a third of the play, long enough to be mapped, is pushed
// 0.3 m aside and left there (issue 66: a thing that was still and mapped, then moves, must not
// capture the pose). Conventional follows the crate's mapped points (35-43 mm over seeds 1-3);
// sdo stays near the oracle (5.6-6.5 against 4.1-4.2).
TEST(PipelineRealBackground, AMappedCratePushedAsideDoesNotCaptureThePose) {
  const auto r =
      RunOverTheRealDesk("pushed_box", {RunMode::kConventional, RunMode::kOracle, RunMode::kSdo});
  if (!r) GTEST_SKIP() << "tum_fr2_desk_50 absent";
  EXPECT_EQ(r->tracked.at(RunMode::kSdo), 99u);
  const double sdo = r->ate.at(RunMode::kSdo), oracle = r->ate.at(RunMode::kOracle);
  EXPECT_LE(sdo, 1.3 * oracle + 0.002) << "sdo " << sdo << " oracle " << oracle;
  // The play tests something only if the mapped crate does pull a pose that ignores motion.
  EXPECT_GT(r->ate.at(RunMode::kConventional), 4 * oracle);
}

// The carried box, a swinging box and a person at once: together they cover more than half of
// the view for long stretches. With the graph segmenter, segments crossed the objects' outlines
// and the check reverted to the dragged pose whenever it left fewer than tracking's 30 inliers
// (50 mm, 8 frames lost); segments that stop at depth edges and concave creases, and a check
// that keeps its static set down to 15 inliers, brought it near the oracle on one noise seed.
// On others it was 11-19 mm: in a few frames the check, started from a pose the movers had
// pulled, took most of the room out. One seed decides nothing here, so three are run and their
// median is held to the bar; every frame of every seed must be tracked.
TEST(PipelineRealBackground, TheBoxASwingingBoxAndAPersonAtOnceDoNotCaptureThePose) {
  std::vector<double> sdo, oracle;
  for (uint32_t seed : {1u, 2u, 3u}) {
    const auto r = RunOverTheRealDesk("mixed", {RunMode::kOracle, RunMode::kSdo}, seed);
    if (!r) GTEST_SKIP() << "tum_fr2_desk_50 absent";
    EXPECT_EQ(r->tracked.at(RunMode::kSdo), 99u) << "seed " << seed;
    sdo.push_back(r->ate.at(RunMode::kSdo));
    oracle.push_back(r->ate.at(RunMode::kOracle));
    ASSERT_EQ(r->sdo_masks.per_class.count("unknown"), 1u);
    EXPECT_GE(r->sdo_masks.per_class.at("unknown").Iou(), 0.6) << "seed " << seed;
    // The person is found by motion alone (no detector knows the rendered box-people); seed 1
    // gave 0.599 while the check judged the carried box feature by feature.
    ASSERT_EQ(r->sdo_masks.per_class.count("person"), 1u);
    EXPECT_GE(r->sdo_masks.per_class.at("person").Iou(), 0.6) << "seed " << seed;
  }
  std::sort(sdo.begin(), sdo.end());
  std::sort(oracle.begin(), oracle.end());
  EXPECT_LE(sdo[1], 1.3 * oracle[1] + 0.002)
      << "median sdo " << sdo[1] << " median oracle " << oracle[1] << "; worst sdo " << sdo[2];
  // No seed may fall apart.
  EXPECT_LE(sdo[2], 3 * oracle[1] + 0.002) << "worst sdo " << sdo[2];
}

// A view gone for a while in the real desk clip played forward and back (99 frames): which
// frames were tracked, and the ATE errors of those before and after the gap.
struct GapOutcome {
  std::vector<bool> tracked;  // per frame
  std::vector<double> error;  // per frame: the ATE error of a tracked one (metres), else NaN
  double ate = 0;
  double rms_before = 0, rms_after = 0;  // tracked frames before `gap_start`, from first_back on
  int first_back = -1;                   // first tracked frame after `gap_end`
};

GapOutcome RunThroughAGap(const std::filesystem::path& sequence, const CameraOptions& camera,
                          RunMode mode, const std::filesystem::path& out, size_t gap_start,
                          size_t gap_end) {
  RunOptions run;
  run.dataset = sequence;
  run.camera = camera;
  run.mode = mode;
  run.slam.sequential = true;
  run.out = out;
  const RunSummary s = RunOnDataset(run);
  const RgbdDataset dataset(sequence, camera);
  GapOutcome g;
  g.tracked.assign(dataset.size(), false);
  g.error.assign(dataset.size(), std::numeric_limits<double>::quiet_NaN());
  std::map<double, size_t> frame_at;
  for (size_t k = 0; k < dataset.size(); ++k) frame_at[dataset.entries()[k].timestamp] = k;
  for (const StampedPose& p : s.trajectory) g.tracked[frame_at.at(p.timestamp)] = true;
  for (size_t k = gap_end; k < g.tracked.size() && g.first_back < 0; ++k) {
    if (g.tracked[k]) g.first_back = static_cast<int>(k);
  }
  const AteResult ate = ComputeAte(*dataset.ground_truth(), s.trajectory);
  g.ate = ate.translation.rmse;
  double before = 0, after = 0;
  int n_before = 0, n_after = 0;
  for (size_t m = 0; m < ate.errors.size(); ++m) {
    const size_t k = frame_at.at(s.trajectory[m].timestamp);
    g.error[k] = ate.errors[m];
    const double e2 = ate.errors[m] * ate.errors[m];
    if (k < gap_start) {
      before += e2;
      ++n_before;
    } else if (g.first_back >= 0 && k >= static_cast<size_t>(g.first_back)) {
      after += e2;
      ++n_after;
    }
  }
  g.rms_before = n_before > 0 ? std::sqrt(before / n_before) : 0;
  g.rms_after = n_after > 0 ? std::sqrt(after / n_after) : 1e9;
  std::cout << ToString(mode) << ": ATE " << g.ate << ", before the gap " << g.rms_before
            << ", after " << g.rms_after << ", first frame back " << g.first_back << '\n';
  return g;
}

// Ten frames of the forward-backward real clip go black on the way back (a hand over the
// lens): they are lost, tracking is back within 5 frames of the view's return, on keyframes of
// the way out, and the frames after are as accurate as those before.
TEST(PipelineRealBackground, TenBlackFramesOnTheWayBackAreLostAndTrackingReturns) {
  testing::TempDir dir;
  const auto written = WriteDeskPlay("static", dir);
  if (!written) GTEST_SKIP() << "tum_fr2_desk_50 absent";
  const synth::BackgroundSynthOptions& options = *written;
  const RgbdDataset dataset(dir / "seq", options.camera);
  ASSERT_EQ(dataset.size(), 99u);
  constexpr size_t kGapStart = 60, kGapEnd = 70;
  for (size_t k = kGapStart; k < kGapEnd; ++k) {
    const RgbdFrameEntry& e = dataset.entries()[k];
    ASSERT_TRUE(cv::imwrite(e.rgb_path.string(), cv::Mat(480, 640, CV_8UC3, cv::Scalar(0, 0, 0))));
    ASSERT_TRUE(cv::imwrite(e.depth_path.string(), cv::Mat(480, 640, CV_16U, cv::Scalar(0))));
  }
  for (RunMode mode : {RunMode::kConventional, RunMode::kSdo}) {
    const GapOutcome g =
        RunThroughAGap(dir / "seq", options.camera, mode, dir / ToString(mode), kGapStart, kGapEnd);
    for (size_t k = kGapStart; k < kGapEnd; ++k) EXPECT_FALSE(g.tracked[k]) << k;
    EXPECT_GE(g.first_back, static_cast<int>(kGapEnd));
    EXPECT_LE(g.first_back, static_cast<int>(kGapEnd) + 5);
    for (size_t k = kGapEnd + 5; k < 99; ++k) EXPECT_TRUE(g.tracked[k]) << k;
    EXPECT_LE(g.rms_after, 1.5 * g.rms_before + 0.002) << ToString(mode);
    EXPECT_LE(g.ate, 0.006) << ToString(mode);
  }
}

// A person walks up to the camera over the real desk (synth person_fills_view, forward and
// back), fills the whole view for most of a second, turns and walks away. No detector knows
// the rendered person; `sdo` must still not follow it: every frame it fills is lost (a frame
// tracked on a strip of desk in between must have the camera's pose), tracking
// is back within 5 frames of the scene's return (the person covering less than 80 % of the
// view), and the frames after are as accurate as those before. Measured: conventional follows
// the person (141 mm); sdo took it for the background once it covered more than half the view
// and drifted 0.4 m with it (69 mm) before large segments the flow-carried memory covers
// stayed dynamic (12 mm; the oracle 7 mm).
TEST(PipelineRealBackground, APersonWhoFillsTheViewIsNotFollowed) {
  testing::TempDir dir;
  const auto written = WriteDeskPlay("person_fills_view", dir);
  if (!written) GTEST_SKIP() << "tum_fr2_desk_50 absent";
  const synth::BackgroundSynthOptions& options = *written;
  const RgbdDataset dataset(dir / "seq", options.camera);
  std::vector<double> coverage;
  for (const RgbdFrameEntry& e : dataset.entries()) {
    const cv::Mat mask = cv::imread((dir / "seq" / "dynamic" / e.rgb_path.filename()).string(),
                                    cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(mask.empty());
    coverage.push_back(static_cast<double>(cv::countNonZero(mask)) / mask.total());
  }
  size_t first_filled = coverage.size(), last_filled = 0;
  for (size_t k = 0; k < coverage.size(); ++k) {
    if (coverage[k] >= 0.99) {
      first_filled = std::min(first_filled, k);
      last_filled = k;
    }
  }
  ASSERT_GE(last_filled, first_filled + 10) << "the person fills the view for ten frames or more";
  size_t scene_back = last_filled + 1;
  while (scene_back < coverage.size() && coverage[scene_back] >= 0.8) ++scene_back;
  ASSERT_LT(scene_back + 10, coverage.size());

  const GapOutcome g = RunThroughAGap(dir / "seq", options.camera, RunMode::kSdo, dir / "sdo",
                                      first_filled, scene_back);
  // Lost while the person fills the view. Between such frames the composited person leaves a
  // strip of the desk in view on some (frame 61 of seed 1: 10 % of the image); tracking such a
  // frame on the desk is right, following the person is not: its pose must be the camera's.
  for (size_t k = first_filled; k <= last_filled; ++k) {
    if (coverage[k] >= 0.99) {
      EXPECT_FALSE(g.tracked[k]) << k;
    } else if (g.tracked[k]) {
      EXPECT_LE(g.error[k], 0.03) << "frame " << k << ", the person covers " << coverage[k];
    }
  }
  EXPECT_GE(g.first_back, 0);
  EXPECT_LE(g.first_back, static_cast<int>(scene_back) + 5)
      << "the scene is back at " << scene_back;
  EXPECT_LE(g.rms_after, 1.5 * g.rms_before + 0.003);
  EXPECT_LE(g.ate, 0.02);
}

}  // namespace
}  // namespace sdoslam

namespace sdoslam {
namespace {

// The same rendered sequence written in the TUM layout and as an Oxford Multi-motion segment
// (Vicon at 200 Hz, a non-trivial camera chain): the same frames must give the same trajectory,
// and each one's ATE against its own ground truth must agree.
TEST(PipelineLayouts, AnOmdSegmentRunsLikeItsTumCopy) {
  testing::TempDir dir;
  synth::SynthOptions synth_options;
  synth_options.scenario = "boxes_unconstrained";
  synth_options.frames = 60;
  synth_options.depth_factor = 1000;  // OMD's millimetres in both copies: the same inputs
  synth::WriteSequence(synth_options, dir / "tum");
  WriteOmdFromTum(dir / "tum", dir / "omd", OmdWriteOptions::ExampleApparatus());

  RunOptions tum_run;
  tum_run.dataset = dir / "tum";
  tum_run.out = dir / "out_tum";
  tum_run.camera = synth::SyntheticCamera();
  tum_run.camera.depth_factor = 1000;
  tum_run.slam.sequential = true;
  RunOptions omd_run = tum_run;
  omd_run.dataset = dir / "omd";
  omd_run.out = dir / "out_omd";
  omd_run.camera = CameraOptions{};  // intrinsics from kalibr.yaml
  omd_run.camera.from_dataset = true;
  omd_run.camera.depth_factor = 1000;
  omd_run.camera.depth_max = synth::SyntheticCamera().depth_max;
  const RunSummary tum = RunOnDataset(tum_run);
  const RunSummary omd = RunOnDataset(omd_run);
  ASSERT_EQ(tum.trajectory.size(), omd.trajectory.size());
  for (size_t k = 0; k < tum.trajectory.size(); ++k) {
    ASSERT_TRUE(tum.trajectory[k].T_world_camera.matrix() ==
                omd.trajectory[k].T_world_camera.matrix())
        << "frame " << k;
  }
  ASSERT_TRUE(tum.evaluation && omd.evaluation);
  EXPECT_EQ(omd.evaluation->ate.errors.size(), tum.evaluation->ate.errors.size());
  EXPECT_NEAR(omd.evaluation->ate.translation.rmse, tum.evaluation->ate.translation.rmse, 1e-4);
  EXPECT_LT(tum.evaluation->ate.translation.rmse, 0.5);  // it tracked (conventional mode)
}

}  // namespace
}  // namespace sdoslam

namespace sdoslam {
namespace {

// A threaded run prepares ahead: it moves the front end and feature extraction of frame k + 1
// into a thread that runs while frame k is tracked, and there (without orb.budget_on_static,
// whose extraction waits for the labels) extracts the features in a task beside the front end
// (extract_beside_front_end). With mapping inline (mapping.concurrent false, the default), that
// must change nothing: a stage that delivered frames out of order, dropped one, or let the front
// end see them in another order would change the trajectory and the per-frame labels, and so
// would local mapping run beside tracking.
TEST(PipelineStages, PreparingAheadGivesTheInlineRunsTrajectoryBitForBit) {
  testing::TempDir dir;
  const auto sequence = testing::WriteShortWalk(dir, 60);
  struct Outcome {
    Trajectory trajectory;
    std::vector<int> dynamic_features;
  };
  auto run_with = [&](bool ahead, size_t capacity, bool budget_on_static) {
    RunOptions run =
        SyntheticRun(sequence, dir / fmt::format("out_{}_{}_{}", ahead, capacity, budget_on_static),
                     RunMode::kSdo);
    run.slam.sequential = !ahead;  // ahead: a threaded run, as `sdoslam run` makes by default
    run.slam.orb.budget_on_static = budget_on_static;
    run.prepare_ahead = ahead;
    run.prepare_queue_capacity = capacity;
    Outcome outcome;
    run.after_frame = [&](const TrackingResult& r, const System&) {
      outcome.dynamic_features.push_back(static_cast<int>(std::count_if(
          r.feature_labels.begin(), r.feature_labels.end(), [](uint8_t l) { return l != 0; })));
    };
    const RunSummary s = RunOnDataset(run);
    EXPECT_EQ(s.frames, 60u);
    outcome.trajectory = s.trajectory;
    return outcome;
  };
  for (bool budget_on_static : {false, true}) {
    const Outcome inline_run = run_with(false, 2, budget_on_static);
    ASSERT_GE(inline_run.trajectory.size(), 55u);
    ASSERT_GT(
        *std::max_element(inline_run.dynamic_features.begin(), inline_run.dynamic_features.end()),
        0);  // the people were seen, so the front end's order matters
    // The queue's capacities with the default budget; the task beside the front end once.
    for (size_t capacity : budget_on_static ? std::vector<size_t>{1, 3} : std::vector<size_t>{1}) {
      const Outcome ahead = run_with(true, capacity, budget_on_static);
      EXPECT_EQ(ahead.dynamic_features, inline_run.dynamic_features)
          << "capacity " << capacity << ", budget_on_static " << budget_on_static;
      ASSERT_EQ(ahead.trajectory.size(), inline_run.trajectory.size());
      for (size_t i = 0; i < ahead.trajectory.size(); ++i) {
        ASSERT_EQ(ahead.trajectory[i].timestamp, inline_run.trajectory[i].timestamp);
        ASSERT_TRUE(ahead.trajectory[i].T_world_camera.matrix() ==
                    inline_run.trajectory[i].T_world_camera.matrix())
            << "frame " << i << ", capacity " << capacity << ", budget_on_static "
            << budget_on_static;
      }
    }
  }
}

// An error in the preparing thread (here: a colour image that cannot be decoded) reaches the
// caller as the Error it was, naming the file, after the frames before it were tracked; it
// neither terminates the process nor hangs the run.
TEST(PipelineStages, AnUnreadableFrameInThePreparingThreadReachesTheCaller) {
  testing::TempDir dir;
  const auto sequence = testing::WriteShortWalk(dir, 30);
  const std::vector<std::filesystem::path> rgb = ColourImages(sequence);
  ASSERT_EQ(rgb.size(), 30u);
  { std::ofstream(rgb[12], std::ios::trunc) << "not a png"; }
  for (bool sequential_mapping : {true, false}) {
    RunOptions run =
        SyntheticRun(sequence, dir / fmt::format("out_{}", sequential_mapping), RunMode::kSdo);
    run.slam.sequential = sequential_mapping;
    run.slam.mapping.concurrent = !sequential_mapping;
    run.prepare_ahead = true;
    size_t frames_tracked_before = 0;
    run.after_frame = [&](const TrackingResult& r, const System&) {
      frames_tracked_before = r.index + 1;
    };
    try {
      RunOnDataset(run);
      ADD_FAILURE() << "the run went through an unreadable frame";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(rgb[12].filename().string()), std::string::npos)
          << e.what();
    }
    EXPECT_EQ(frames_tracked_before, 12u);
  }
}

// Stopping a run that prepares ahead ends it at once with what was tracked; the preparing
// thread, possibly waiting on a full queue, is stopped and joined.
TEST(PipelineStages, AnInterruptedRunThatPreparesAheadStopsCleanly) {
  testing::TempDir dir;
  const auto sequence = testing::WriteShortWalk(dir, 40);
  RunOptions run = SyntheticRun(sequence, dir / "out", RunMode::kConventional);
  run.slam.sequential = false;
  size_t seen = 0;
  run.after_frame = [&](const TrackingResult&, const System&) { ++seen; };
  run.stop_requested = [&] { return seen >= 15; };
  const RunSummary s = RunOnDataset(run);
  EXPECT_TRUE(s.interrupted);
  EXPECT_EQ(s.frames, 15u);
  EXPECT_EQ(seen, 15u);
  EXPECT_GE(s.trajectory.size(), 13u);
}

// The loop looked for a stop only before a frame: a signal during the last frame left the set
// marked "complete", and `sdoslam run` exited 0 after printing "interrupted". A stop asked for
// before the commit marks the set "interrupted" (the command then exits 130 or 143).
TEST(PipelineStages, AStopDuringTheLastFrameMarksTheRunInterrupted) {
  testing::TempDir dir;
  const auto sequence = testing::WriteShortWalk(dir, 5);
  for (bool prepare_ahead : {false, true}) {
    RunOptions run =
        SyntheticRun(sequence, dir / fmt::format("out_{}", prepare_ahead), RunMode::kConventional);
    run.prepare_ahead = prepare_ahead;
    std::atomic<bool> stop{false};
    run.after_frame = [&](const TrackingResult& r, const System&) {
      if (r.index == 4) stop = true;  // the signal, arriving while the last frame is in hand
    };
    run.stop_requested = [&] { return stop.load(); };
    const RunSummary s = RunOnDataset(run);
    EXPECT_TRUE(s.interrupted) << "prepare_ahead " << prepare_ahead;
    EXPECT_EQ(s.frames, 5u);
    EXPECT_EQ(ReadResultManifest(run.out).status, "interrupted");
  }
}

// An image replaced by a FIFO during a run blocked the reader for good. Each read checks that it
// reads a regular file: the run fails naming the image, inline and reading ahead alike.
TEST(PipelineStages, AnImageSwappedForAFifoMidRunIsNamedInsteadOfWaitedFor) {
  testing::TempDir dir;
  const auto sequence = testing::WriteShortWalk(dir, 12);
  const std::vector<std::filesystem::path> rgb = ColourImages(sequence);
  ASSERT_EQ(rgb.size(), 12u);
  const std::filesystem::path image = rgb[9], kept = dir / "kept.png";
  std::filesystem::copy_file(image, kept);
  for (bool prepare_ahead : {false, true}) {
    RunOptions run =
        SyntheticRun(sequence, dir / fmt::format("out_{}", prepare_ahead), RunMode::kConventional);
    run.prepare_ahead = prepare_ahead;
    run.after_frame = [&](const TrackingResult& r, const System&) {
      if (r.index != 2) return;  // the dataset was opened (and checked) long before
      std::filesystem::remove(image);
      ASSERT_EQ(mkfifo(image.c_str(), 0600), 0);
    };
    EXPECT_EQ(testing::MessageOf([&] { RunOnDataset(run); }),
              image.string() + ": not a regular file")
        << "prepare_ahead " << prepare_ahead;
    std::filesystem::remove(image);
    std::filesystem::copy_file(kept, image);
  }
}

// At the camera's rate, frame i is read no earlier than i periods after the first: six frames of
// a 2 Hz camera take at least 2.5 s, which the same run without pacing takes a fraction of
// (tens of milliseconds a frame). The setting travels in the run's config.yaml, which reruns it.
TEST(PipelineStages, FramesReadAtTheCameraRateArriveOnePeriodApart) {
  testing::TempDir dir;
  const auto sequence = testing::WriteShortWalk(dir, 6);
  for (bool sequential : {true, false}) {
    RunOptions run =
        SyntheticRun(sequence, dir / fmt::format("out_{}", sequential), RunMode::kConventional);
    run.camera.fps = 2;
    run.camera_rate = true;
    run.slam.sequential = sequential;
    const auto start = std::chrono::steady_clock::now();
    const RunSummary s = RunOnDataset(run);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    EXPECT_EQ(s.frames, 6u);
    EXPECT_GE(seconds, 2.5) << "sequential " << sequential;
    EXPECT_GE(s.wall_ms_per_frame * 6, 2500 * 0.99) << "sequential " << sequential;
    EXPECT_TRUE(LoadRunConfig(run.out / "config.yaml").camera_rate);
  }
}

// Mask scoring is evaluation, not SLAM: turned off (as bench does), a run on a synthetic sequence
// gives no mask scores and the same trajectory.
TEST(PipelineStages, MaskScoringCanBeLeftOutWithoutChangingTheRun) {
  testing::TempDir dir;
  const auto sequence = testing::WriteShortWalk(dir, 20);
  auto run_with = [&](bool evaluate) {
    RunOptions run = SyntheticRun(sequence, dir / fmt::format("out_{}", evaluate), RunMode::kSdo);
    run.slam.sequential = true;
    run.evaluate_masks = evaluate;
    return RunOnDataset(run);
  };
  const RunSummary scored = run_with(true), unscored = run_with(false);
  ASSERT_TRUE(scored.masks.has_value());
  EXPECT_EQ(scored.masks->frames, scored.frames);
  EXPECT_GT(scored.masks->pixels.true_positive + scored.masks->pixels.false_negative, 0u);
  EXPECT_FALSE(unscored.masks.has_value());
  ASSERT_EQ(unscored.trajectory.size(), scored.trajectory.size());
  ASSERT_GE(scored.trajectory.size(), 15u);
  for (size_t i = 0; i < scored.trajectory.size(); ++i) {
    ASSERT_TRUE(unscored.trajectory[i].T_world_camera.matrix() ==
                scored.trajectory[i].T_world_camera.matrix())
        << "frame " << i;
  }
}

// run --save-objects over the synthetic OMD-style boxes (three pendulums and a sliding box), with
// the ground-truth masks (oracle): each box is followed under one id on almost every frame, and
// its own motion frame to frame is measured to millimetres and fractions of a degree
// (eval-objects' scores). The camera's trajectory is the one a run without objects gives.
TEST(PipelineOutputs, EachSwingingBoxIsFollowedUnderOneIdWithItsOwnMotion) {
  testing::TempDir dir;
  const auto sequence = WriteScenario("boxes_translational", dir, 60);
  auto run_with = [&](bool objects) {
    RunOptions run = SyntheticRun(sequence, dir / fmt::format("out_{}", objects), RunMode::kOracle);
    run.slam.sequential = true;
    run.save_objects = objects;
    return RunOnDataset(run);
  };
  const RunSummary with = run_with(true), without = run_with(false);
  ASSERT_EQ(with.trajectory.size(), without.trajectory.size());
  for (size_t i = 0; i < with.trajectory.size(); ++i) {
    ASSERT_TRUE(with.trajectory[i].T_world_camera.matrix() ==
                without.trajectory[i].T_world_camera.matrix())
        << "frame " << i;
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "out_false" / "objects.csv"));
  const ObjectEvaluation e = EvaluateObjects(sequence, dir / "out_true");
  ASSERT_EQ(e.bodies.size(), 4u);
  for (const BodyScore& b : e.bodies) {
    SCOPED_TRACE(b.body);
    ASSERT_FALSE(b.ids.empty());
    EXPECT_EQ(b.frames_in_view, 60u);
    EXPECT_GE(b.frames_main_id, 54u);  // 90 % of the frames under one id
    // The main id's track, brought into the ground truth's world, moves with its box: every
    // centroid within 40 cm of where the box carried the centroid's mean position. (The centroid
    // of the faces in view shifts as a box turns and enters the view: 7-32 cm at most here. A
    // track left in the run's own world, whose origin is the first camera's, would be metres
    // off.)
    const ObjectTrack& track = e.tracks.at(b.ids.front());
    EXPECT_EQ(track.body, b.body);
    ASSERT_EQ(track.centroids.size(), b.frames_main_id);
    ASSERT_EQ(track.true_centroids.size(), b.frames_main_id);
    double farthest = 0;
    for (size_t k = 0; k < track.centroids.size(); ++k) {
      ASSERT_TRUE(track.true_centroids[k].has_value());
      farthest = std::max(farthest, (track.centroids[k] - *track.true_centroids[k]).norm());
    }
    EXPECT_LT(farthest, 0.4);
    EXPECT_TRUE(std::filesystem::exists(dir / "out_true" / "objects" /
                                        fmt::format("{}.txt", b.ids.front())));
    ASSERT_GE(b.translation_errors.size(), 50u);
    EXPECT_LT(ComputeErrorStats(b.translation_errors).rmse, 0.007);
    EXPECT_LT(ComputeErrorStats(b.rotation_errors_deg).rmse, 1.0);
  }
}

// A run config's objects: section sets the object tracker; a bad value names its key and file.
TEST(PipelineOutputs, TheObjectsSectionIsReadAndCheckedByKey) {
  testing::TempDir dir;
  const std::string camera = testing::ReadText(testing::SourceDir() / "configs" / "tum_fr2.yaml");
  testing::WriteText(dir / "good.yaml", camera + "objects: {min_votes: 7, gate_m: 0.25}\n");
  const RunOptions run = LoadRunConfig(dir / "good.yaml");
  EXPECT_EQ(run.objects.min_votes, 7);
  EXPECT_EQ(run.objects.gate_m, 0.25);
  EXPECT_EQ(run.objects.min_pixels, ObjectTrackerOptions().min_pixels);
  testing::WriteText(dir / "bad.yaml", camera + "objects: {min_votes: 0}\n");
  const std::string message = testing::MessageOf([&] { LoadRunConfig(dir / "bad.yaml"); });
  EXPECT_NE(message.find("bad.yaml"), std::string::npos) << message;
  EXPECT_NE(message.find("objects.min_votes"), std::string::npos) << message;
  testing::WriteText(dir / "unknown.yaml", camera + "objects: {min_vote: 3}\n");
  EXPECT_NE(testing::MessageOf([&] { LoadRunConfig(dir / "unknown.yaml"); }).find("min_vote"),
            std::string::npos);
}

// mapping.csv names why a keyframe got no local BA: `spaced` when one ran fewer than
// min_frames_between_local_ba frames before, `skipped` only when it gave way to a waiting
// keyframe, which a sequential run never does. With a spacing longer than the walk, every
// keyframe after the first adjusted one is spaced.
TEST(PipelineOutputs, MappingLogTellsSpacedBundleAdjustmentsFromSkippedOnes) {
  testing::TempDir dir;
  const auto sequence = testing::WriteShortWalk(dir, 60);
  RunOptions run = SyntheticRun(sequence, dir / "out", RunMode::kConventional);
  run.slam.sequential = true;
  run.slam.mapping.min_frames_between_local_ba = 1000;
  const RunSummary s = RunOnDataset(run);
  size_t adjusted = 0, spaced = 0;
  for (const MappingRecord& m : s.mapping) {
    adjusted += m.result.ba.iterations > 0;
    spaced += m.result.ba_spaced;
    EXPECT_FALSE(m.result.ba_skipped) << "keyframe of frame " << m.frame_index;
  }
  EXPECT_EQ(adjusted, 1u);
  ASSERT_GE(spaced, 1u) << s.mapping.size() << " keyframes";
  std::istringstream log(testing::ReadText(dir / "out" / "mapping.csv"));
  std::string line;
  std::getline(log, line);
  size_t column = 0;
  for (size_t start = 0; line.substr(start, line.find(',', start) - start) != "ba_stopped";
       start = line.find(',', start) + 1) {
    ASSERT_NE(line.find(',', start), std::string::npos) << "no ba_stopped column: " << line;
    ++column;
  }
  size_t spaced_rows = 0, rows = 0;
  while (std::getline(log, line)) {
    std::istringstream fields(line);
    std::string field;
    for (size_t c = 0; c <= column; ++c) std::getline(fields, field, ',');
    ++rows;
    spaced_rows += field == "spaced";
    EXPECT_NE(field, "skipped") << line;
  }
  EXPECT_EQ(rows, s.mapping.size());
  EXPECT_EQ(spaced_rows, spaced);
}

}  // namespace
}  // namespace sdoslam
