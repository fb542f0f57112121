// The library's entry point, frame by frame: what a caller of Pipeline sees.
#include "sdoslam/pipeline/pipeline.h"

#include <gtest/gtest.h>

#include <chrono>
#include <opencv2/imgproc.hpp>
#include <thread>

#include "sdoslam/core/error.h"
#include "sdoslam/io/dataset.h"
#include "sdoslam/synth/scenarios.h"
#include "sdoslam/testing/short_walk.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

// A frame that waits between Prepare and Finish (as a frame read ahead waits in the queue for
// tracking) reports the wait as queued_ms, and its latency leaves it out: the latency is the
// frame's own time, which a camera's frame sees when the system keeps up with the camera.
TEST(PipelineStages, TheWaitBeforeTrackingIsQueuedTimeNotLatency) {
  testing::TempDir dir;
  const auto sequence = testing::WriteShortWalk(dir, 1);
  const RgbdDataset dataset(sequence, synth::SyntheticCamera());
  PipelineOptions options;
  options.camera = synth::SyntheticCamera();
  Pipeline pipeline(options);
  RgbdFrame frame = dataset.Load(0);
  const auto start = std::chrono::steady_clock::now();
  StagedFrame staged = pipeline.Prepare(frame);
  constexpr double kWaitMs = 300;
  std::this_thread::sleep_for(std::chrono::duration<double, std::milli>(kWaitMs));
  const FrameOutput out = pipeline.Finish(std::move(staged));
  const double elapsed_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  EXPECT_GE(out.queued_ms, kWaitMs);
  EXPECT_GT(out.latency_ms, 0);
  EXPECT_LE(out.latency_ms, elapsed_ms - kWaitMs) << "the wait counted as latency";
  EXPECT_LE(out.latency_ms + out.queued_ms, elapsed_ms);
}

// A library user's own segmentation: features under the caller's mask are never tracked, in
// conventional mode too, and inputs of the wrong size fail naming the frame.
TEST(PipelineStages, ACallersMaskTakesItsFeaturesOut) {
  testing::TempDir dir;
  const auto sequence = testing::WriteShortWalk(dir, 2);
  const RgbdDataset dataset(sequence, synth::SyntheticCamera());
  PipelineOptions options;
  options.camera = synth::SyntheticCamera();
  Pipeline pipeline(options);
  RgbdFrame frame = dataset.Load(0);
  cv::Mat mask(frame.bgr.size(), CV_8U, cv::Scalar(0));
  mask(cv::Rect(0, 0, mask.cols / 2, mask.rows)).setTo(255);  // the left half
  const FrameOutput out = pipeline.Track(frame, mask);
  const TrackingResult& r = out.tracking;
  ASSERT_GT(r.feature_points.size(), 100u);
  int left = 0, right = 0;
  for (size_t k = 0; k < r.feature_points.size(); ++k) {
    const bool in_mask = r.feature_points[k].x < mask.cols / 2 - 1;
    const bool out_of_mask = r.feature_points[k].x >= mask.cols / 2 + 1;
    if (in_mask) {
      ++left;
      EXPECT_NE(r.feature_labels[k], 0) << "feature " << k << " under the mask";
    }
    if (out_of_mask) {
      ++right;
      EXPECT_EQ(r.feature_labels[k], 0) << "feature " << k << " outside the mask";
    }
  }
  EXPECT_GT(left, 20);
  EXPECT_GT(right, 20);

  cv::Mat small;
  cv::resize(frame.bgr, small, cv::Size(320, 240));
  try {
    RgbdFrame next = frame;
    next.index = 1;
    next.bgr = small;
    pipeline.Track(next);
    ADD_FAILURE() << "a 320x240 image was taken";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("frame 1"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace sdoslam
