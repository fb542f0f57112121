#include "sdoslam/apps/bench_command.h"

#include <fmt/format.h>

#include <algorithm>
#include <iostream>
#include <memory>

#include "sdoslam/apps/pipeline.h"
#include "sdoslam/apps/run_command.h"
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
  RunOverrides overrides;
};

double Median(const std::vector<double>& v) { return ComputeErrorStats(v).median; }

// Runs the same sequence several times and reports the median over runs of each run's median
// per-frame and per-keyframe times: this machine is noisy, single runs are not worth quoting.
void RunBench(const BenchArgs& args) {
  std::filesystem::path dataset = args.dataset;
  RunOptions base;
  if (dataset.empty()) {
    if (!args.config.empty()) throw Error("--config needs --dataset");
    dataset = std::filesystem::path(args.work) / "static_room_halfsphere";
    synth::SynthOptions synth_options;
    synth_options.scenario = "static_room";
    synth_options.motion = synth::CameraMotion::kHalfsphere;
    synth_options.frames = 150;
    synth::WriteSequence(synth_options, dataset, /*overwrite=*/true);
    base.camera = synth::SyntheticCamera();
  } else {
    if (args.config.empty()) throw Error("--config is required with --dataset");
    base = LoadRunConfig(args.config);
  }
  args.overrides.ApplyTo(&base);
  base.slam.sequential = !args.threaded;
  base.dataset = dataset;
  const bool front_end = base.mode == RunMode::kSdo;
  std::vector<double> frame_ms, mapping_ms, ate, total_ms, front_ms;
  std::vector<double> segment_ms, detect_ms, flow_ms, classify_ms;
  for (int run = 0; run < args.runs; ++run) {
    RunOptions run_options = base;
    run_options.out = std::filesystem::path(args.work) / fmt::format("run{}", run);
    const RunSummary s = RunOnDataset(run_options);
    frame_ms.push_back(s.median_frame_ms);
    mapping_ms.push_back(s.median_mapping_ms);
    total_ms.push_back(s.median_total_ms);
    front_ms.push_back(s.median_front_end_ms);
    segment_ms.push_back(s.median_front_end_stages.segment_ms);
    detect_ms.push_back(s.median_front_end_stages.detect_ms);
    flow_ms.push_back(s.median_front_end_stages.flow_ms);
    classify_ms.push_back(s.median_front_end_stages.classify_ms);
    if (s.evaluation) ate.push_back(s.evaluation->ate.translation.rmse);
    std::cout << fmt::format(
        "run {}: {:.1f} ms/frame{}, {:.1f} ms/keyframe{}\n", run + 1, s.median_total_ms,
        front_end ? fmt::format(" (front end {:.1f})", s.median_front_end_ms) : "",
        s.median_mapping_ms,
        s.evaluation ? fmt::format(", ATE {:.4f} m", s.evaluation->ate.translation.rmse) : "");
  }
  std::cout << fmt::format("{} ({}, mode {}, {} runs), medians:\n", dataset.string(),
                           args.threaded ? "threaded" : "sequential", ToString(base.mode),
                           args.runs);
  if (front_end) {
    std::cout << fmt::format(
        "  front end {:.1f} ms/frame (segment {:.1f}, detect {:.1f} [{}], flow {:.1f} [{}], "
        "classify {:.1f})\n",
        Median(front_ms), Median(segment_ms), Median(detect_ms), base.front_end.detector,
        Median(flow_ms), base.front_end.flow, Median(classify_ms));
  }
  std::cout << fmt::format(
      "  features + tracking {:.1f} ms/frame; per frame in all {:.1f} ms; local mapping {:.1f} "
      "ms/keyframe{}\n",
      Median(frame_ms), Median(total_ms), Median(mapping_ms),
      ate.empty() ? "" : fmt::format("; ATE {:.4f} m", Median(ate)));
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
  args->overrides.AddTo(cmd);
  cmd->callback([args] { RunBench(*args); });
}

}  // namespace sdoslam
