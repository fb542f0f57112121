#include "sdoslam/apps/bench_command.h"

#include <fmt/format.h>

#include <algorithm>
#include <iostream>
#include <memory>

#include "sdoslam/apps/bench_matrix.h"
#include "sdoslam/apps/run_command.h"
#include "sdoslam/core/error.h"
#include "sdoslam/core/memory.h"
#include "sdoslam/runner/run_on_dataset.h"
#include "sdoslam/synth/scenarios.h"
#include "sdoslam/synth/sequence.h"

namespace sdoslam {
namespace {

struct BenchArgs {
  std::string dataset;
  std::string config;
  std::string scenario = "static_room";  // the built-in sequence, without --dataset
  std::string motion = "halfsphere";
  int frames = 150;
  int block = 0;  // > 0: the soak report, per block of this many frames
  int runs = 5;
  bool threaded = false;
  bool camera_rate = false;
  std::string work = "sdoslam_bench";
  RunOverrides overrides;
  // The matrix (bench_matrix.h): given --sequences, sequences × modes → one table.
  std::vector<std::string> sequences;
  std::vector<std::string> modes = BenchMatrixArgs().modes;
  std::string table;
};

double Median(const std::vector<double>& v) { return ComputeErrorStats(v).median; }

// The state at the end of one block of frames, sampled while the run goes on.
struct BlockEnd {
  size_t last_frame = 0;
  double first_timestamp = 0, last_timestamp = 0;
  size_t keyframes_alive = 0, map_points_alive = 0;
  size_t resident_bytes = 0;
  int lost = 0;
};

// The soak report: does a long run stay as fast, as small and as accurate as a short one?
// Per block: local mapping per keyframe (median, p95, and the median of each stage), the map's
// size and the process's resident memory at the block's end, and the frame ATE of the block's
// frames (the whole run aligned once).
void PrintBlocks(const RunSummary& s, const std::vector<BlockEnd>& blocks) {
  std::cout << fmt::format(
      "{:>11} {:>4} {:>8} {:>8} {:>8} {:>8} {:>6} {:>6} {:>6} {:>6} {:>6} {:>5} {:>6} {:>7} "
      "{:>8} {:>5}\n",
      "frames", "kf", "map_med", "map_p95", "cpu_med", "cpu_p95", "insert", "triang", "fuse", "ba",
      "cull", "alive", "points", "rss_MB", "ATE_mm", "lost");
  size_t first = 0;
  for (const BlockEnd& b : blocks) {
    std::vector<double> ms, cpu, insert, triangulate, fuse, ba, cull;
    for (const MappingRecord& m : s.mapping) {
      if (m.frame_index < first || m.frame_index > b.last_frame) continue;
      ms.push_back(m.ms);
      cpu.push_back(m.cpu_ms);
      insert.push_back(m.result.insert_ms);
      triangulate.push_back(m.result.triangulate_ms);
      fuse.push_back(m.result.fuse_ms);
      ba.push_back(m.result.ba_ms);
      cull.push_back(m.result.cull_ms);
    }
    std::vector<double> errors;
    if (s.evaluation) {
      const AteResult& ate = s.evaluation->ate;
      for (size_t k = 0; k < ate.errors.size(); ++k) {
        if (ate.timestamps[k] >= b.first_timestamp - 1e-6 &&
            ate.timestamps[k] <= b.last_timestamp + 1e-6)
          errors.push_back(ate.errors[k]);
      }
    }
    std::cout << fmt::format(
        "{:>5}-{:<5} {:>4} {:>8.1f} {:>8.1f} {:>8.1f} {:>8.1f} {:>6.1f} {:>6.1f} {:>6.1f} {:>6.1f} "
        "{:>6.1f} {:>5} {:>6} {:>7.1f} {:>8} {:>5}\n",
        first, b.last_frame, ms.size(), Median(ms), Percentile(ms, 0.95), Median(cpu),
        Percentile(cpu, 0.95), Median(insert), Median(triangulate), Median(fuse), Median(ba),
        Median(cull), b.keyframes_alive, b.map_points_alive,
        static_cast<double>(b.resident_bytes) / (1 << 20),
        errors.empty() ? "-" : fmt::format("{:.1f}", 1000 * ComputeErrorStats(errors).rmse),
        b.lost);
    first = b.last_frame + 1;
  }
  if (s.evaluation) {
    const ErrorStats& f = s.evaluation->ate.translation;
    std::cout << fmt::format("frame ATE {:.1f} mm (max {:.1f} mm)", 1000 * f.rmse, 1000 * f.max);
    if (s.keyframe_evaluation) {
      std::cout << fmt::format("; keyframe ATE {:.1f} mm ({} keyframes alive)",
                               1000 * s.keyframe_evaluation->ate.translation.rmse,
                               s.keyframe_trajectory.size());
      if (s.keyframe_ate_in_frame_alignment) {
        std::cout << fmt::format(", {:.1f} mm under the frames' alignment",
                                 1000 * s.keyframe_ate_in_frame_alignment->translation.rmse);
      }
    }
    std::cout << '\n';
  }
}

// The run options of a bench: the dataset and config given, or a synthetic scenario rendered
// into the work folder once and reused.
RunOptions BenchBase(const BenchArgs& args) {
  std::filesystem::path dataset = args.dataset;
  RunOptions base;
  if (dataset.empty()) {
    if (!args.config.empty()) throw Error("--config needs --dataset");
    dataset = std::filesystem::path(args.work) /
              fmt::format("{}_{}_{}", args.scenario, args.motion, args.frames);
    synth::MakeScenario(args.scenario, 1.0);  // an unknown name throws before any rendering
    synth::SynthOptions synth_options;
    synth_options.scenario = args.scenario;
    synth_options.motion = synth::ParseCameraMotion(args.motion);
    synth_options.frames = args.frames;
    if (!std::filesystem::exists(dataset / "groundtruth.txt")) {  // rendered once, then reused
      std::cout << fmt::format("rendering {} frames of {} ({})...\n", args.frames, args.scenario,
                               args.motion);
      synth::WriteSequence(synth_options, dataset, /*overwrite=*/true);
    }
    base.camera = synth::SyntheticCamera();
  } else {
    if (args.config.empty()) throw Error("--config is required with --dataset");
    base = LoadRunConfig(args.config);
  }
  base.dataset = dataset;
  return base;
}

// Runs the same sequence several times and reports the median over runs of each run's median
// per-frame and per-keyframe times: this machine is noisy, single runs are not worth quoting.
void RunBench(const BenchArgs& args) {
  RunOptions base = BenchBase(args);
  args.overrides.ApplyTo(&base);
  base.slam.sequential = !args.threaded;
  base.camera_rate = args.camera_rate;
  const std::filesystem::path& dataset = base.dataset;
  base.evaluate_masks = false;  // no mask scores here: the timings are the system's alone
  const bool front_end = base.mode == RunMode::kSdo;
  std::vector<double> frame_ms, mapping_ms, ate, total_ms, front_ms;
  std::vector<double> segment_ms, detect_ms, flow_ms, classify_ms;
  for (int run = 0; run < args.runs; ++run) {
    RunOptions run_options = base;
    run_options.out = std::filesystem::path(args.work) / fmt::format("run{}", run);
    std::vector<BlockEnd> blocks;
    if (args.block > 0) {
      run_options.after_frame = [&](const TrackingResult& r, const System&) {
        const size_t block = r.index / static_cast<size_t>(args.block);
        if (blocks.size() <= block) {
          blocks.emplace_back();
          blocks.back().first_timestamp = r.timestamp;
        }
        BlockEnd& b = blocks.back();
        b.last_frame = r.index;
        b.last_timestamp = r.timestamp;
        b.keyframes_alive = r.keyframes_alive;
        b.map_points_alive = r.map_points_alive;
        b.lost += r.state == TrackingState::kLost;
        b.resident_bytes = ResidentBytes();
      };
    }
    const RunSummary s = RunOnDataset(run_options);
    if (args.block > 0) PrintBlocks(s, blocks);
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
                           std::string(args.threaded ? "threaded" : "sequential") +
                               (args.camera_rate ? ", at the camera's rate" : ""),
                           ToString(base.mode), args.runs);
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
  CLI::App* cmd = app.add_subcommand(
      "bench",
      "time SLAM runs (medians over repeated runs); with --sequences, the table of sequences × "
      "modes");
  CLI::Option* dataset =
      cmd->add_option("--dataset", args->dataset,
                      "sequence (default: a synthetic sequence, --scenario, --motion, --frames)");
  CLI::Option* scenario =
      cmd->add_option("--scenario", args->scenario, "built-in sequence: synthetic scenario")
          ->capture_default_str();
  CLI::Option* motion =
      cmd->add_option("--motion", args->motion, "built-in sequence: camera motion")
          ->capture_default_str();
  cmd->add_option("--frames", args->frames,
                  "built-in sequences: frames (rendered once into --work)")
      ->check(CLI::Range(10, 100000))
      ->capture_default_str();
  CLI::Option* block =
      cmd->add_option("--block", args->block,
                      "soak report: per block of this many frames, mapping ms per keyframe "
                      "(median, p95, stages), keyframes and map points alive, resident memory, "
                      "frame ATE")
          ->check(CLI::Range(1, 1000000));
  cmd->add_option("--config", args->config,
                  "config YAML for --dataset (with --sequences: for every dataset folder; "
                  "default there: the folder's camera.yaml)");
  cmd->add_option("--runs", args->runs, "number of runs (of each row, with --sequences)")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  cmd->add_flag("--threaded", args->threaded,
                "read and prepare frames ahead in threads (default: sequential)");
  cmd->add_flag("--camera-rate", args->camera_rate,
                "read the frames at the camera's rate (camera.fps), as a live camera gives them: "
                "fps then says whether the system keeps up, latency is a camera's");
  cmd->add_option("--work", args->work, "folder for outputs")->capture_default_str();
  args->overrides.AddTo(cmd);
  CLI::Option* sequences =
      cmd->add_option("--sequences", args->sequences,
                      "the table's sequences, comma-separated: synth:<scenario>[:<motion>] "
                      "(built in, --frames frames; default motion: the scenario's own) or a "
                      "dataset folder (--config or its camera.yaml)")
          ->delimiter(',');
  sequences->excludes(dataset)->excludes(scenario)->excludes(motion)->excludes(block);
  sequences->excludes(cmd->get_option("--mode"));  // --modes gives the rows' modes
  cmd->add_option("--modes", args->modes,
                  "with --sequences: the modes, comma-separated (oracle: n/a for a sequence "
                  "without ground-truth masks)")
      ->delimiter(',')
      ->capture_default_str()
      ->needs(sequences);
  cmd->add_option("--table", args->table,
                  "with --sequences: also write the Markdown table to this file")
      ->needs(sequences);
  cmd->callback([args, sequences] {
    if (sequences->count() == 0) return RunBench(*args);
    BenchMatrixArgs matrix;
    matrix.sequences = args->sequences;
    matrix.modes = args->modes;
    matrix.config = args->config;
    matrix.table = args->table;
    matrix.work = args->work;
    matrix.frames = args->frames;
    matrix.runs = args->runs;
    matrix.threaded = args->threaded;
    matrix.camera_rate = args->camera_rate;
    matrix.overrides = args->overrides;
    RunBenchMatrix(matrix);
  });
}

}  // namespace sdoslam
