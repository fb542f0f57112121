// Google Benchmark micro-benchmarks of the hot paths. Not tests: run them by hand,
//   build/bench/micro_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <random>

#include "sdoslam/dynamic/geometric_segmenter.h"
#include "sdoslam/dynamic/lab.h"
#include "sdoslam/features/orb_extractor.h"
#include "sdoslam/io/dataset.h"
#include "sdoslam/map/map.h"
#include "sdoslam/optim/optimizer.h"
#include "sdoslam/optim/pose_graph.h"
#include "sdoslam/synth/renderer.h"
#include "sdoslam/synth/scenarios.h"
#include "sdoslam/testing/single_feature_keyframe.h"

namespace sdoslam {
namespace {

FrontEndFrame SyntheticFrame() {
  const synth::Scenario s = synth::MakeScenario("walking_xyz", 10.0);
  const Camera camera(synth::SyntheticCamera());
  const synth::RenderedView view =
      synth::Render(s.scene, 2.0, synth::CameraPoseAt(s.motion, 2.0, 10.0), camera);
  FrontEndFrame frame;
  view.colour.convertTo(frame.bgr, CV_8UC3, 255.0);
  frame.depth = view.depth;
  return frame;
}

cv::Mat SyntheticGray() {
  cv::Mat gray;
  cv::cvtColor(SyntheticFrame().bgr, gray, cv::COLOR_BGR2GRAY);
  return gray;
}

// The two class-agnostic segmenters that need no file, on one rendered 640 x 480 RGB-D frame.
void BM_SegmentRgbdGraph(benchmark::State& state) {
  const FrontEndFrame frame = SyntheticFrame();
  RgbdSegmenter segmenter;
  for (auto _ : state) benchmark::DoNotOptimize(segmenter.Segment(frame).count);
}
BENCHMARK(BM_SegmentRgbdGraph)->Unit(benchmark::kMillisecond);

void BM_SegmentGeometric(benchmark::State& state) {
  const FrontEndFrame frame = SyntheticFrame();
  GeometricSegmenterOptions options;
  options.work_width = static_cast<int>(state.range(0));
  GeometricSegmenter segmenter(options, Camera(synth::SyntheticCamera()).K(), frame.bgr.size());
  for (auto _ : state) benchmark::DoNotOptimize(segmenter.Segment(frame).count);
}
BENCHMARK(BM_SegmentGeometric)->Arg(320)->Arg(240)->Arg(160)->Unit(benchmark::kMillisecond);

// The same on a real frame (TUM fr2_desk, frame 25 of the 50 in ../shared): its depth has holes
// and noise that a rendered frame lacks, and the segmenter's own loops (edges, creases, the
// growth into holes) cost more than OpenCV's normals there.
void BM_SegmentGeometricDesk(benchmark::State& state) {
  const std::filesystem::path folder =
      std::filesystem::path(SDOSLAM_SHARED_DIR) / "data" / "tum_fr2_desk_50";
  if (!std::filesystem::exists(folder)) {
    state.SkipWithError("../shared/data/tum_fr2_desk_50 is absent");
    return;
  }
  const RgbdDataset dataset(
      folder, LoadCameraConfig(std::filesystem::path(SDOSLAM_SOURCE_DIR) / "configs/tum_fr2.yaml"));
  const RgbdFrame rgbd = dataset.Load(25);
  FrontEndFrame frame;
  frame.bgr = rgbd.bgr;
  frame.depth = rgbd.depth;
  GeometricSegmenter segmenter({}, Camera(dataset.camera()).K(), frame.bgr.size());
  for (auto _ : state) benchmark::DoNotOptimize(segmenter.Segment(frame).count);
}
BENCHMARK(BM_SegmentGeometricDesk)->Unit(benchmark::kMillisecond);

// Lab of the segmenter's 320 x 240 work image: ours against OpenCV's float conversion, which it
// replaced (dynamic/lab.h: OpenCV's first call also builds tables for 140-270 ms, not timed here).
cv::Mat WorkImage() {
  cv::Mat small;
  cv::resize(SyntheticFrame().bgr, small, cv::Size(320, 240), 0, 0, cv::INTER_AREA);
  return small;
}
void BM_LabOurs(benchmark::State& state) {
  const cv::Mat bgr = WorkImage();
  cv::Mat lab;
  for (auto _ : state) {
    BgrToLab(bgr, &lab);
    benchmark::DoNotOptimize(lab.data);
  }
}
BENCHMARK(BM_LabOurs)->Unit(benchmark::kMillisecond);
void BM_LabOpenCv(benchmark::State& state) {
  const cv::Mat bgr = WorkImage();
  cv::Mat f, lab;
  for (auto _ : state) {
    bgr.convertTo(f, CV_32F, 1.0 / 255.0);
    cv::cvtColor(f, lab, cv::COLOR_BGR2Lab);
    benchmark::DoNotOptimize(lab.data);
  }
}
BENCHMARK(BM_LabOpenCv)->Unit(benchmark::kMillisecond);

void BM_OrbExtract640x480(benchmark::State& state) {
  const cv::Mat gray = SyntheticGray();
  const OrbExtractor orb(OrbOptions{});
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  for (auto _ : state) {
    orb.Extract(gray, &keypoints, &descriptors);
    benchmark::DoNotOptimize(descriptors.data);
  }
  state.counters["features"] = static_cast<double>(keypoints.size());
}
BENCHMARK(BM_OrbExtract640x480)->Unit(benchmark::kMillisecond);

// A Kinect-like camera: TUM freiburg1 focal lengths and centre, bf = 40 (focal length times
// baseline, px m) for the virtual right image.
PinholeIntrinsics KinectIntrinsics() { return {535.4, 539.2, 320.1, 247.6, 40.0}; }

void BM_OptimizePose(benchmark::State& state) {
  const PinholeIntrinsics k = KinectIntrinsics();
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> xy(-2, 2), z(1, 5);
  std::vector<Eigen::Vector3d> points;
  std::vector<PointObservation> observations;
  for (int i = 0; i < state.range(0); ++i) {
    const Eigen::Vector3d p(xy(rng), xy(rng), z(rng));
    PointObservation m;
    m.pixel = Eigen::Vector2d(k.fx * p.x() / p.z() + k.cx + 0.5, k.fy * p.y() / p.z() + k.cy - 0.5);
    m.right_u = m.pixel.x() - k.bf / p.z();
    points.push_back(p);
    observations.push_back(m);
  }
  Eigen::Isometry3d initial = Eigen::Isometry3d::Identity();
  initial.translation() = Eigen::Vector3d(0.02, -0.01, 0.03);
  for (auto _ : state)
    benchmark::DoNotOptimize(OptimizePose(k, initial, points, observations).num_inliers);
}
BENCHMARK(BM_OptimizePose)->Arg(300)->Arg(800)->Unit(benchmark::kMillisecond);

// A local bundle adjustment the size of the mixed play's (mapping.csv there: 11 free keyframes,
// a few fixed ones, about 700 points and 2,600 observations, 85 % with depth): keyframes 3 cm
// apart looking at a room 1-4 m away, each point seen by the keyframes it projects into (at
// most 5), poses and points perturbed by millimetres and 5 % outliers. Not a test: the timing
// of a solve of this shape, for comparing solver settings.
BundleAdjustmentProblem LocalWindowProblem() {
  const PinholeIntrinsics k = KinectIntrinsics();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> xy(-1.5, 1.5), z(1, 4), unit(0, 1);
  std::normal_distribution<double> pixel_noise(0, 1), mm(0, 0.003);
  BundleAdjustmentProblem ba;
  const int kPoses = 14, kFixed = 3, kPoints = 700;
  for (int i = 0; i < kPoses; ++i) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(0.01 * i, Eigen::Vector3d::UnitY()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(-0.03 * i, 0.005 * i, 0);
    ba.poses.push_back(T);
    ba.pose_fixed.push_back(i < kFixed);
  }
  for (int p = 0; p < kPoints; ++p) {
    const Eigen::Vector3d X(xy(rng), xy(rng), z(rng));
    const int first = static_cast<int>(unit(rng) * kPoses);
    int seen = 0;
    for (int i = first; i < kPoses && seen < 5; ++i) {
      const Eigen::Vector3d c = ba.poses[static_cast<size_t>(i)] * X;
      PointObservation m;
      m.pixel = Eigen::Vector2d(k.fx * c.x() / c.z() + k.cx, k.fy * c.y() / c.z() + k.cy);
      if (m.pixel.x() < 0 || m.pixel.x() > 640 || m.pixel.y() < 0 || m.pixel.y() > 480) continue;
      const double outlier = unit(rng) < 0.05 ? 8.0 : 1.0;
      m.pixel += outlier * Eigen::Vector2d(pixel_noise(rng), pixel_noise(rng));
      if (unit(rng) < 0.85) m.right_u = m.pixel.x() - k.bf / c.z() + pixel_noise(rng);
      m.inv_sigma2 = std::pow(1.2, -2 * static_cast<int>(unit(rng) * 4));
      ba.observations.push_back({i, static_cast<int>(ba.points.size()), m});
      ++seen;
    }
    ba.points.push_back(X + Eigen::Vector3d(mm(rng), mm(rng), mm(rng)));
  }
  for (int i = kFixed; i < kPoses; ++i)
    ba.poses[static_cast<size_t>(i)].translation() += Eigen::Vector3d(mm(rng), mm(rng), mm(rng));
  return ba;
}

void BM_BundleAdjustLocalWindow(benchmark::State& state) {
  const PinholeIntrinsics k = KinectIntrinsics();
  const BundleAdjustmentProblem start = LocalWindowProblem();
  BundleAdjustmentStats stats;
  for (auto _ : state) {
    state.PauseTiming();
    BundleAdjustmentProblem ba = start;
    state.ResumeTiming();
    benchmark::DoNotOptimize(BundleAdjust(k, &ba, {}, &stats).size());
  }
  state.counters["observations"] = stats.observations;
  state.counters["iterations"] = stats.iterations;
}
BENCHMARK(BM_BundleAdjustLocalWindow)->Unit(benchmark::kMillisecond);

// The essential graph of a long sequence: state.range(0) keyframes 15 cm apart, each linked to
// its next 10, every node but the first moved by centimetres before the solve (the loop
// closer's budget; pose_graph_test checks the result).
void BM_OptimizePoseGraph(benchmark::State& state) {
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0, 0.02);
  PoseGraphProblem truth;
  for (int k = 0; k < state.range(0); ++k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(0.01 * k, Eigen::Vector3d::UnitY()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(0.15 * k, 0, 0);
    truth.poses.push_back(T);
  }
  for (int i = 0; i < state.range(0); ++i) {
    for (int j = i + 1; j <= i + 10 && j < state.range(0); ++j)
      truth.edges.push_back({i, j, truth.poses[i] * truth.poses[j].inverse(), 1.0});
  }
  truth.fixed.assign(truth.poses.size(), false);
  truth.fixed[0] = true;
  for (auto _ : state) {
    state.PauseTiming();
    PoseGraphProblem g = truth;
    for (size_t k = 1; k < g.poses.size(); ++k)
      g.poses[k].translation() += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    state.ResumeTiming();
    benchmark::DoNotOptimize(OptimizePoseGraph(&g).final_cost);
  }
}
BENCHMARK(BM_OptimizePoseGraph)->Arg(500)->Unit(benchmark::kMillisecond);

// A map point's representative descriptor with state.range(0) observers: quadratic up to
// MapPoint::kMaxDescriptorCandidates, flat beyond (conventional tracking in a dynamic scene
// gives points hundreds of observers).
void BM_UpdateDescriptor(benchmark::State& state) {
  CameraOptions o;
  o.fx = o.fy = 500;
  o.cx = 320;
  o.cy = 240;
  const Camera camera(o);
  const OrbExtractor extractor(OrbOptions{});
  const auto geometry = std::make_shared<FrameGeometry>(camera, extractor, 40.0, 3.0);
  cv::RNG rng(1);
  Map map;
  MapPoint* p = nullptr;
  for (int64_t v = 0; v < state.range(0); ++v) {
    cv::Mat descriptor(1, 32, CV_8U);
    rng.fill(descriptor, cv::RNG::UNIFORM, 0, 256);
    KeyFrame* kf = testing::AddSingleFeatureKeyFrame(map, static_cast<size_t>(v), descriptor,
                                                     geometry, extractor);
    if (p == nullptr) p = map.AddMapPoint(Eigen::Vector3d(0, 0, 2), kf);
    map.AddObservation(p, kf, 0);
  }
  for (auto _ : state) {
    p->UpdateDescriptor();
    benchmark::DoNotOptimize(p->descriptor.data);
  }
}
BENCHMARK(BM_UpdateDescriptor)->Arg(30)->Arg(64)->Arg(200)->Arg(500)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace sdoslam
