#include "sdoslam/apps/run_command.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <iostream>
#include <memory>

#include "sdoslam/apps/pipeline.h"
#include "sdoslam/core/atomic_file.h"
#include "sdoslam/core/error.h"

namespace sdoslam {
namespace {

struct RunArgs {
  std::string dataset;
  std::string config;
  std::string out;
  std::string associations;
  std::string layout = "auto";
  int max_frames = 0;
  bool sequential = false;
  RunOverrides overrides;
  bool save_overlays = false;
  bool save_masks = false;
};

void RunSlam(const RunArgs& args) {
  // Everything that can be wrong with the inputs is found before the first frame.
  RunOptions run = LoadRunConfig(args.config);
  args.overrides.ApplyTo(&run);
  run.slam.sequential = args.sequential;
  run.dataset = args.dataset;
  run.associations = args.associations;
  run.layout = ParseDatasetLayout(args.layout);
  run.out = args.out;
  run.max_frames = static_cast<size_t>(args.max_frames);
  run.save_overlays = args.save_overlays;
  run.save_masks = args.save_masks;
  const RunSummary s = RunOnDataset(run);
  std::cout << FormatRunSummary(s) << "wrote " << args.out
            << "/CameraTrajectory.txt, KeyFrameTrajectory.txt, config.yaml, frames.csv"
            << (args.save_masks ? ", masks/, features.csv" : "")
            << (args.save_overlays ? ", overlays/" : "") << "\n";
  if (s.masks) std::cout << '\n' << FormatMaskEvaluation(*s.masks, "dynamic masks");
  if (s.evaluation) std::cout << '\n' << FormatTable({*s.evaluation}, EvaluationOptions{});
}

}  // namespace

void AddRunCommand(CLI::App& app) {
  auto args = std::make_shared<RunArgs>();
  CLI::App* cmd = app.add_subcommand(
      "run", "RGB-D SLAM on a sequence (TUM, Bonn, sdoslam synth, Oxford Multi-motion)");
  cmd->add_option("--dataset", args->dataset,
                  "sequence folder: TUM layout (rgb.txt, depth.txt, rgb/, depth/) or an OMD "
                  "segment (rgbd/, vicon.csv, vicon.yaml, kalibr.yaml)")
      ->required();
  cmd->add_option("--layout", args->layout,
                  "folder layout: auto (by its files; rgbd_bonn_* folders are bonn), tum, omd, "
                  "bonn (TUM files, ground truth of the markers brought to the camera)")
      ->check(CLI::IsMember({"auto", "tum", "omd", "bonn"}));
  cmd->add_option(
         "--config", args->config,
         "config YAML: camera: and optional orb:, rgbd:, tracking:, consistency:, mapping:, "
         "dynamic:")
      ->required();
  cmd->add_option("--out", args->out, "output folder")->required();
  cmd->add_option("--associations", args->associations, "explicit rgb/depth association file");
  cmd->add_option("--max-frames", args->max_frames, "stop after this many frames (0: all)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--sequential", args->sequential,
                "map inline after each keyframe: bit-identical runs (default: a mapping thread)");
  args->overrides.AddTo(cmd);
  cmd->add_flag("--save-overlays", args->save_overlays,
                "write overlays/<frame>.png: features (static green, dynamic red), segments, "
                "motion boundaries, detections");
  cmd->add_flag("--save-masks", args->save_masks,
                "write masks/<frame>.png (0 static, 1 known movable, 2 moving unknown) and "
                "features.csv, for sdoslam eval-masks");
  cmd->callback([args] { RunSlam(*args); });
}

void RunOverrides::AddTo(CLI::App* cmd) {
  cmd->add_option("--mode", mode,
                  "conventional (all features), sdo (the dynamic front end), oracle (ground-truth "
                  "masks of a synthetic sequence); default: the config's mode: or conventional");
  cmd->add_option("--segmenter", segmenter,
                  "override dynamic.segmenter.backend: rgbd, onnx-yoloseg, file");
  cmd->add_option(
      "--detector", detector,
      "override dynamic.detector.backend: nanodet, fastestdet, yolov8, hog, file, none");
  cmd->add_option("--segmenter-model", segmenter_model,
                  "ONNX file of the segmenter (onnx-yoloseg: a Fast-SAM / YOLOv8-seg export)");
  cmd->add_option("--detector-model", detector_model, "ONNX file of the detector");
  cmd->add_option("--flow", flow, "override dynamic.flow.backend: dis, farneback, onnx");
  cmd->add_option("--flow-model", flow_model, "ONNX file of a learned flow network (flow onnx)");
  cmd->add_option("--consistency", consistency,
                  "mode sdo: the scene-flow consistency check and map hygiene, on (default) or "
                  "off; overrides consistency.enabled")
      ->check(CLI::IsMember({"on", "off"}));
}

void RunOverrides::ApplyTo(RunOptions* run) const {
  if (!mode.empty()) run->mode = ParseRunMode(mode);
  if (!segmenter.empty()) run->front_end.segmenter = segmenter;
  if (!segmenter_model.empty()) run->front_end.segmenter_model = segmenter_model;
  if (!detector.empty()) run->front_end.detector = detector;
  if (!detector_model.empty()) run->front_end.detector_model = detector_model;
  if (!flow.empty()) run->front_end.flow = flow;
  if (!flow_model.empty()) run->front_end.flow_model = flow_model;
  run->front_end.Check();
  if (!consistency.empty()) run->slam.tracking.consistency.enabled = consistency == "on";
}

}  // namespace sdoslam
