#include "sdoslam/pipeline/pipeline.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <future>
#include <opencv2/imgproc.hpp>

#include "sdoslam/core/error.h"

namespace sdoslam {

const char* ToString(RunMode mode) {
  switch (mode) {
    case RunMode::kConventional:
      return "conventional";
    case RunMode::kSdo:
      return "sdo";
    case RunMode::kOracle:
      return "oracle";
  }
  return "?";
}

RunMode ParseRunMode(const std::string& name) {
  for (RunMode m : {RunMode::kConventional, RunMode::kSdo, RunMode::kOracle}) {
    if (name == ToString(m)) return m;
  }
  throw Error("unknown mode '" + name + "' (known: conventional, sdo, oracle)");
}

static_assert(kSceneFlow == kSceneFlowLabel, "the front end and tracking name label 3 alike");
static_assert(kMovingUnknown == kMotionSelectedLabel, "... and label 2 alike");

Pipeline::Pipeline(const PipelineOptions& options) : options_(options) {
  if (options_.mode == RunMode::kSdo) {
    const cv::Size image_size(options_.camera.width, options_.camera.height);
    front_end_ = std::make_unique<FrontEnd>(options_.front_end, options_.dataset_folder, image_size,
                                            options_.rgb_paths, Camera(options_.camera).K());
  }
  slam_ = std::make_unique<System>(options_.camera, options_.slam);
}

Pipeline::~Pipeline() = default;

FrameOutput Pipeline::Track(RgbdFrame input, const cv::Mat& dynamic_mask) {
  return Finish(Prepare(std::move(input), dynamic_mask));
}

StagedFrame Pipeline::Prepare(RgbdFrame input, const cv::Mat& dynamic_mask) {
  StagedFrame staged;
  staged.started = std::chrono::steady_clock::now();
  const cv::Size image_size(options_.camera.width, options_.camera.height);
  if (input.bgr.size() != image_size || input.bgr.type() != CV_8UC3 ||
      input.depth.size() != image_size || input.depth.type() != CV_32FC1) {
    throw Error(fmt::format(
        "frame {} ({}): expected a {}x{} 8-bit colour image and a 32-bit float depth image of "
        "the same size",
        input.index, input.rgb_path.string(), image_size.width, image_size.height));
  }
  if (!dynamic_mask.empty() &&
      (dynamic_mask.size() != image_size || dynamic_mask.type() != CV_8UC1))
    throw Error(fmt::format("frame {}: the dynamic mask is not 8-bit single-channel {}x{}",
                            input.index, image_size.width, image_size.height));
  cv::Mat segments;
  // The grey image is made once a frame: feature extraction, the consistency check and the
  // front end's flow share it.
  cv::Mat gray;
  cv::cvtColor(input.bgr, gray, cv::COLOR_BGR2GRAY);
  std::optional<PreparedFrame> features;
  // With orb.budget_on_static the features are spread over what the labels call static, and
  // wait for them: the front end's budget labels (SdoResult::budget_labels), with a caller's
  // mask.
  const bool budget_on_static = options_.slam.orb.budget_on_static;
  cv::Mat budget_labels;
  auto extract = [&] {
    features.emplace(slam_->ExtractFeatures(input.index, input.timestamp, input.bgr, input.depth,
                                            gray, budget_on_static ? budget_labels : cv::Mat()));
  };
  // A thread of its own (tens of microseconds to start against 10 ms of work; ThreadSanitizer sees
  // its synchronisation, which it would not in a TBB task). The future's destructor waits for it on
  // every way out, exceptions included, before `features` goes.
  std::future<void> extraction;
  const bool beside = front_end_ && options_.extract_beside_front_end && !budget_on_static;
  if (beside) extraction = std::async(std::launch::async, extract);
  if (front_end_) {
    const FrontEndFrame frame{input, gray};
    staged.sdo = front_end_->Process(frame, &staged.front_end_timing);
    staged.labels = staged.sdo->labels;
    segments = staged.sdo->segments.labels;
    for (uint8_t l : staged.sdo->segment_labels)
      staged.locked_segments.push_back(l == kKnownMovable);
  }
  if (!dynamic_mask.empty()) {
    // The caller's mask joins the front end's verdict; where both speak, the front end's class
    // is kept.
    if (staged.labels.empty()) {
      staged.labels = cv::Mat(image_size, CV_8U, cv::Scalar(kStatic));
    } else {
      staged.labels = staged.labels.clone();
    }
    staged.labels.setTo(kMovingUnknown, (dynamic_mask != 0) & (staged.labels == kStatic));
  }
  // The budget's labels are the labels, unless the front end left a first selection's inside in
  // the budget; a caller's mask stays out of it either way.
  if (staged.sdo && staged.sdo->budget_labels.data != staged.sdo->labels.data) {
    budget_labels = staged.sdo->budget_labels;
    if (!dynamic_mask.empty()) {
      budget_labels = budget_labels.clone();
      budget_labels.setTo(kMovingUnknown, dynamic_mask != 0);
    }
  } else {
    budget_labels = staged.labels;
  }
  if (beside) {
    extraction.get();  // rethrows the extraction's exception
  } else {
    extract();
  }
  slam_->AddDynamicInputs(&*features, staged.labels, segments, staged.locked_segments,
                          staged.sdo ? staged.sdo->unmapped : cv::Mat());
  // The check may return the front end's motion-selected features to static, never a caller's
  // mask (ground truth).
  if (features->consistency)
    features->consistency->motion_selected_recheckable =
        front_end_ != nullptr && dynamic_mask.empty();
  staged.slam.emplace(std::move(*features));
  staged.input = std::move(input);
  staged.prepared = std::chrono::steady_clock::now();
  return staged;
}

FrameOutput Pipeline::Finish(StagedFrame&& staged) {
  if (!staged.slam) throw Error("Pipeline::Finish: a frame that was not prepared");
  const auto finish_start = std::chrono::steady_clock::now();
  FrameOutput out;
  out.tracking = slam_->Track(std::move(*staged.slam), &out.timing);
  out.labels = staged.labels;
  if (!out.tracking.check_segments.empty() && staged.sdo) {
    // The consistency check's verdict joins the front end's in the masks, overlays and scores.
    const cv::Mat& segments = staged.sdo->segments.labels;
    const cv::Size image_size(staged.input.bgr.size());
    out.labels = out.labels.clone();
    cv::Mat turned(segments.size(), CV_8U, cv::Scalar(0));
    for (int id : out.tracking.check_segments) turned.setTo(255, segments == id);
    cv::resize(turned, turned, image_size, 0, 0, cv::INTER_NEAREST);
    out.labels.setTo(kSceneFlow, turned & (out.labels == kStatic));
  }
  out.sdo = std::move(staged.sdo);
  out.front_end_timing = staged.front_end_timing;
  out.input = std::move(staged.input);
  using Ms = std::chrono::duration<double, std::milli>;
  out.queued_ms = Ms(finish_start - staged.prepared).count();
  out.latency_ms = Ms(std::chrono::steady_clock::now() - staged.started).count() - out.queued_ms;
  return out;
}

}  // namespace sdoslam
