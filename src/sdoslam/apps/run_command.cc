#include "sdoslam/apps/run_command.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <memory>

#include "sdoslam/apps/exit_codes.h"
#include "sdoslam/core/atomic_file.h"
#include "sdoslam/core/error.h"
#include "sdoslam/core/interrupt.h"
#include "sdoslam/runner/run_on_dataset.h"

namespace sdoslam {
namespace {

// The options whose defaults must not override a config's run: section: set only when given.
struct RunCommandOptions {
  CLI::Option* layout = nullptr;
  CLI::Option* max_frames = nullptr;
};

struct RunArgs {
  std::string dataset;
  std::string config;
  std::string out;
  std::string associations;
  std::string layout = "auto";
  int max_frames = 0;
  bool sequential = false;
  bool camera_rate = false;
  RunOverrides overrides;
  bool save_overlays = false;
  bool save_masks = false;
  bool save_map = false;
  bool save_objects = false;
};

// Options of the dynamic front end say so when the mode has no front end.
void WarnAboutOptionsWithoutEffect(const RunOverrides& o, RunMode mode) {
  if (mode == RunMode::kSdo) return;
  for (const auto& [flag, value] : {std::pair{"--segmenter", &o.segmenter},
                                    {"--segmenter-model", &o.segmenter_model},
                                    {"--detector", &o.detector},
                                    {"--detector-model", &o.detector_model},
                                    {"--flow", &o.flow},
                                    {"--flow-model", &o.flow_model},
                                    {"--consistency", &o.consistency}}) {
    if (!value->empty()) {
      spdlog::warn("{} has no effect in mode {}: only mode sdo runs the dynamic front end", flag,
                   ToString(mode));
    }
  }
}

// On a terminal, one progress line redrawn in place at most 4 times a second, and ended (also
// when the run fails, so that the message starts on a line of its own); in a log file or a pipe,
// a plain log line every 500 frames.
class ProgressLine {
 public:
  ~ProgressLine() { End(); }
  void Show(const RunProgress& p) {
    if (!terminal_) {
      if (p.frames_done % 500 == 0) spdlog::info("{}", FormatRunProgress(p));
      return;
    }
    const auto now = std::chrono::steady_clock::now();
    const bool last = p.frames_done == p.frames_requested;
    if (drawn_ && !last && now - last_drawn_ < std::chrono::milliseconds(250)) return;
    last_drawn_ = now;
    drawn_ = true;
    std::fprintf(stderr, "\r%s\033[K", FormatRunProgress(p).c_str());
    std::fflush(stderr);
  }
  void End() {
    if (drawn_) std::fprintf(stderr, "\n");
    drawn_ = false;
  }

 private:
  const bool terminal_ = isatty(STDERR_FILENO) == 1;
  bool drawn_ = false;
  std::chrono::steady_clock::time_point last_drawn_;
};

void RunSlam(const RunArgs& args, const RunCommandOptions& given) {
  // Everything that can be wrong with the inputs is found before the first frame.
  RunOptions run = LoadRunConfig(args.config);
  args.overrides.ApplyTo(&run);
  WarnAboutOptionsWithoutEffect(args.overrides, run.mode);
  // The command line wins over a config's run: section (a run's own config.yaml has one).
  if (!args.dataset.empty()) run.dataset = args.dataset;
  if (run.dataset.empty()) {
    // A usage error (exit code 2), as a missing required option is.
    throw CLI::RequiredError("--dataset (or a config with run.dataset, as a run's config.yaml)");
  }
  if (given.layout->count() > 0) run.layout = ParseDatasetLayout(args.layout);
  if (!args.associations.empty()) run.associations = args.associations;
  if (given.max_frames->count() > 0) run.max_frames = static_cast<size_t>(args.max_frames);
  run.slam.sequential = run.slam.sequential || args.sequential;
  run.save_overlays = run.save_overlays || args.save_overlays;
  run.save_masks = run.save_masks || args.save_masks;
  run.save_map = run.save_map || args.save_map;
  run.save_objects = run.save_objects || args.save_objects;
  run.camera_rate = run.camera_rate || args.camera_rate;
  run.out = args.out;
  InterruptHandler interrupts;
  run.stop_requested = [] { return InterruptHandler::Requested(); };
  ProgressLine progress_line;
  run.progress = [&](const RunProgress& p) { progress_line.Show(p); };
  const RunSummary s = RunOnDataset(run);
  progress_line.End();
  std::cout << FormatRunSummary(s) << "wrote " << args.out
            << "/CameraTrajectory.txt, KeyFrameTrajectory.txt, config.yaml, frames.csv, "
               "mapping.csv, loops.csv"
            << (run.save_masks ? ", masks/, features.csv" : "")
            << (run.save_overlays ? ", overlays/" : "")
            << (run.save_map ? fmt::format(", map.ply ({} static points)", s.map_cloud_points) : "")
            << (run.save_objects ? ", objects.csv, objects/" : "") << ", manifest.json\n";
  if (s.masks) std::cout << '\n' << FormatMaskEvaluation(*s.masks, "dynamic masks");
  if (s.evaluation) std::cout << '\n' << FormatTable({*s.evaluation}, EvaluationOptions{});
  if (s.interrupted) {
    std::cout << fmt::format(
        "interrupted after {} of {} frames: the results so far are written, marked "
        "\"interrupted\" in manifest.json\n",
        s.frames, s.requested);
    const int signal = InterruptHandler::ReceivedSignal();
    throw ExitRequest{signal == SIGTERM ? kExitTerminated : kExitInterrupted};
  }
}

}  // namespace

void AddRunCommand(CLI::App& app) {
  auto args = std::make_shared<RunArgs>();
  CLI::App* cmd = app.add_subcommand(
      "run", "RGB-D SLAM on a sequence (TUM, Bonn, sdoslam synth, Oxford Multi-motion)");
  auto given = std::make_shared<RunCommandOptions>();
  cmd->add_option(
      "--dataset", args->dataset,
      "sequence folder: TUM layout (rgb.txt, depth.txt, rgb/, depth/) or an OMD "
      "segment (rgbd/, vicon.csv, vicon.yaml, kalibr.yaml); default: the config's run.dataset");
  given->layout =
      cmd->add_option("--layout", args->layout,
                      "folder layout: auto (by its files; rgbd_bonn_* folders are bonn), tum, omd, "
                      "bonn (TUM files, ground truth of the markers brought to the camera)")
          ->check(CLI::IsMember({"auto", "tum", "omd", "bonn"}));
  cmd->add_option(
         "--config", args->config,
         "config YAML: camera: and optional orb:, rgbd:, tracking:, mapping:, loop_closing:, "
         "vocabulary:, dynamic: (docs/configuration.md: the keys)")
      ->required();
  cmd->add_option("--out", args->out, "output folder")->required();
  cmd->add_option("--associations", args->associations, "explicit rgb/depth association file");
  given->max_frames =
      cmd->add_option("--max-frames", args->max_frames, "stop after this many frames (0: all)")
          ->check(CLI::NonNegativeNumber);
  cmd->add_flag(
      "--sequential", args->sequential,
      "one thread for everything (default: frames read and prepared ahead in threads; the same "
      "trajectory)");
  cmd->add_flag("--camera-rate", args->camera_rate,
                "read the frames at the camera's rate (camera.fps), as a live camera gives them: "
                "the latency is then a camera's");
  args->overrides.AddTo(cmd);
  cmd->add_flag("--save-overlays", args->save_overlays,
                "write overlays/<frame>.png: features (static green, dynamic red), segments, "
                "motion boundaries, detections");
  cmd->add_flag("--save-masks", args->save_masks,
                "write masks/<frame>.png (0 static, 1 known movable, 2 moving unknown) and "
                "features.csv, for sdoslam eval-masks");
  cmd->add_flag("--save-map", args->save_map,
                "write map.ply: the static map as a coloured point cloud (points on things found "
                "moving left out), for MeshLab, CloudCompare or Open3D");
  cmd->add_flag("--save-objects", args->save_objects,
                "write objects.csv (each moving object's id, class, own motion, centroid and size "
                "per frame) and objects/<id>.txt (its centroid track, TUM format), for sdoslam "
                "eval-objects");
  cmd->callback([args, given] { RunSlam(*args, *given); });
}

void RunOverrides::AddTo(CLI::App* cmd) {
  cmd->add_option("--mode", mode,
                  "conventional (all features), sdo (the dynamic front end), oracle (ground-truth "
                  "masks of a synthetic sequence); default: the config's mode: or conventional");
  cmd->add_option("--segmenter", segmenter,
                  "override dynamic.segmenter.backend: rgbd, geometric, onnx-yoloseg, file");
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
                  "off; overrides tracking.consistency.enabled")
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
