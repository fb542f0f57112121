#include "sdoslam/apps/demo_command.h"

#include <fmt/format.h>

#include <iostream>
#include <memory>

#include "sdoslam/pipeline/pipeline.h"
#include "sdoslam/eval/report.h"
#include "sdoslam/io/trajectory.h"
#include "sdoslam/synth/sequence.h"

namespace sdoslam {
namespace {

struct DemoArgs {
  std::string out = "sdoslam_demo";
  unsigned seed = 1;
  int frames = 150;
};

// The main job on built-in data: render a static room and the same room with people walking
// through it (same camera motion), run SLAM and evaluate against the ground truth: conventional
// on both, then the dynamic front end (sdo) and the ground-truth-mask oracle on the walking one.
// The rendered people are boxes no COCO detector knows, so the demo's known-object detections
// come from the renderer (the `file` detector backend); moving objects of no known class would be
// found by motion.
void RunDemo(const DemoArgs& args) {
  const std::filesystem::path out = args.out;
  std::cout << "sdoslam demo: synthetic sequence -> SLAM -> evaluation (nothing downloaded)\n\n";
  std::vector<EstimateEvaluation> evaluations;
  for (const char* scenario : {"static_room", "walking_xyz"}) {
    synth::SynthOptions synth_options;
    synth_options.scenario = scenario;
    synth_options.motion = synth::CameraMotion::kXyz;
    synth_options.frames = args.frames;
    synth_options.seed = args.seed;
    const auto sequence = out / scenario;
    const synth::SequenceSummary rendered =
        synth::WriteSequence(synth_options, sequence, /*overwrite=*/true);
    std::cout << fmt::format(
        "{}: rendered {} frames in {:.1f} s; moving objects cover {:.0f} % of the image\n",
        scenario, rendered.frames, rendered.total_seconds, 100.0 * rendered.dynamic_fraction_mean);
    std::vector<RunMode> modes = {RunMode::kConventional};
    if (std::string(scenario) != "static_room")
      modes = {RunMode::kConventional, RunMode::kSdo, RunMode::kOracle};
    for (RunMode mode : modes) {
      RunOptions run_options;
      run_options.dataset = sequence;
      run_options.camera = synth::SyntheticCamera();
      run_options.mode = mode;
      run_options.front_end.detector = "file";
      run_options.front_end.detections_file = "detections.json";
      run_options.out = out / "slam" / fmt::format("{}_{}", scenario, ToString(mode));
      RunSummary run = RunOnDataset(run_options);
      std::cout << ToString(mode) << ": " << FormatRunSummary(run);
      if (run.masks && mode == RunMode::kSdo)
        std::cout << FormatMaskEvaluation(*run.masks, "sdo masks");
      std::cout << '\n';
      if (run.evaluation) {
        run.evaluation->label = fmt::format("{} {}", scenario, ToString(mode));
        evaluations.push_back(*run.evaluation);
      }
    }
  }
  const EvaluationOptions options;
  std::cout << FormatTable(evaluations, options);
  WriteEvaluationPlots(evaluations, options, out / "plots");
  std::cout << "\nsequences, trajectories and plots in " << out.string() << "/\n";
}

}  // namespace

void AddDemoCommand(CLI::App& app) {
  auto args = std::make_shared<DemoArgs>();
  CLI::App* cmd = app.add_subcommand("demo", "run the built-in demo (no dataset, no download)");
  cmd->add_option("--out", args->out, "output folder")->capture_default_str();
  cmd->add_option("--seed", args->seed, "seed of the sensor noise")->capture_default_str();
  cmd->add_option("--frames", args->frames, "frames per sequence")
      ->check(CLI::Range(30, 100000))
      ->capture_default_str();
  cmd->callback([args] { RunDemo(*args); });
}

}  // namespace sdoslam
