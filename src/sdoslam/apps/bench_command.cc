#include "sdoslam/apps/bench_command.h"

#include <fmt/format.h>

#include <algorithm>
#include <iostream>
#include <memory>

#include "sdoslam/apps/pipeline.h"
#include "sdoslam/core/error.h"
#include "sdoslam/synth/sequence.h"

namespace sdoslam {
namespace {

struct BenchArgs {
  std::string dataset;
  std::string config;
  int runs = 5;
  bool threaded = false;
  std::string work = "sdoslam_bench";
};

// Runs the same sequence several times and reports the median over runs of each run's median
// per-frame and per-keyframe time: this machine is noisy, single runs are not worth quoting.
void RunBench(const BenchArgs& args) {
  std::filesystem::path dataset = args.dataset;
  CameraOptions camera;
  SlamOptions options;
  if (dataset.empty()) {
    dataset = std::filesystem::path(args.work) / "static_room_halfsphere";
    synth::SynthOptions synth_options;
    synth_options.scenario = "static_room";
    synth_options.motion = synth::CameraMotion::kHalfsphere;
    synth_options.frames = 150;
    synth::WriteSequence(synth_options, dataset, /*overwrite=*/true);
    camera = synth::SyntheticCamera();
  } else {
    if (args.config.empty()) throw Error("--config is required with --dataset");
    ConfigMap root = ConfigMap::LoadFile(args.config);
    std::optional<ConfigMap> section = root.Section("camera");
    if (!section) throw Error(args.config + ": missing the 'camera:' section");
    camera = ReadCameraOptions(*section);
    options = ReadSlamOptions(root);
    root.RejectUnknownKeys();
  }
  options.sequential = !args.threaded;
  std::vector<double> frame_ms, mapping_ms, ate;
  for (int run = 0; run < args.runs; ++run) {
    RunOptions run_options;
    run_options.dataset = dataset;
    run_options.camera = camera;
    run_options.slam = options;
    run_options.out = std::filesystem::path(args.work) / fmt::format("run{}", run);
    const RunSummary s = RunOnDataset(run_options);
    frame_ms.push_back(s.median_frame_ms);
    mapping_ms.push_back(s.median_mapping_ms);
    if (s.evaluation) ate.push_back(s.evaluation->ate.translation.rmse);
    std::cout << fmt::format(
        "run {}: {:.1f} ms/frame, {:.1f} ms/keyframe{}\n", run + 1, s.median_frame_ms,
        s.median_mapping_ms,
        s.evaluation ? fmt::format(", ATE {:.4f} m", s.evaluation->ate.translation.rmse) : "");
  }
  std::cout << fmt::format(
      "{} ({}, {} runs): median per frame (features + tracking) {:.1f} ms, median local mapping "
      "per "
      "keyframe {:.1f} ms{}\n",
      dataset.string(), args.threaded ? "threaded" : "sequential", args.runs,
      ComputeErrorStats(frame_ms).median, ComputeErrorStats(mapping_ms).median,
      ate.empty() ? "" : fmt::format(", median ATE {:.4f} m", ComputeErrorStats(ate).median));
}

}  // namespace

void AddBenchCommand(CLI::App& app) {
  auto args = std::make_shared<BenchArgs>();
  CLI::App* cmd = app.add_subcommand("bench", "time SLAM runs (medians over repeated runs)");
  cmd->add_option("--dataset", args->dataset,
                  "sequence (default: a synthetic static_room halfsphere sequence)");
  cmd->add_option("--config", args->config, "config YAML for --dataset");
  cmd->add_option("--runs", args->runs, "number of runs")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  cmd->add_flag("--threaded", args->threaded, "map in a thread (default: sequential)");
  cmd->add_option("--work", args->work, "folder for outputs")->capture_default_str();
  cmd->callback([args] { RunBench(*args); });
}

}  // namespace sdoslam
