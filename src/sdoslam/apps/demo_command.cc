#include "sdoslam/apps/demo_command.h"

#include <fmt/format.h>

#include <iostream>
#include <memory>
#include <random>

#include "sdoslam/eval/report.h"
#include "sdoslam/io/trajectory.h"
#include "sdoslam/synth/sequence.h"

namespace sdoslam {
namespace {

struct DemoArgs {
  std::string out = "sdoslam_demo";
  unsigned seed = 1;
};

// Renders a short synthetic dynamic sequence (two people walking, camera moving as in TUM
// walking_xyz) with its ground truth, then evaluates two simulated estimates of its trajectory:
// one with white noise, one that also drifts in scale and yaw. Until the SLAM pipeline exists,
// this is what the demo can honestly show: the test bed and the evaluation.
void RunDemo(const DemoArgs& args) {
  const std::filesystem::path out = args.out;
  synth::SynthOptions synth_options;
  synth_options.scenario = "walking_xyz";
  synth_options.frames = 150;
  synth_options.seed = args.seed;
  const synth::SequenceSummary summary =
      synth::WriteSequence(synth_options, out / "walking_xyz", /*overwrite=*/true);
  std::cout << fmt::format(
      "sdoslam demo\n1. rendered {} frames of the synthetic scenario walking_xyz to {} in {:.1f} "
      "s;\n"
      "   people cover {:.0f} % of the image on average\n",
      summary.frames, (out / "walking_xyz").string(), summary.total_seconds,
      100.0 * summary.dynamic_fraction_mean);

  const Trajectory ground_truth = ReadTumTrajectory(out / "walking_xyz" / "groundtruth.txt");
  std::mt19937 rng(args.seed);
  std::normal_distribution<double> noise(0.0, 0.005);
  Trajectory noisy, drifting;
  const double t0 = ground_truth.front().timestamp;
  for (const StampedPose& pose : ground_truth) {
    StampedPose a = pose;
    a.T_world_camera.translation() += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    noisy.push_back(a);
    const double s = pose.timestamp - t0;
    StampedPose b = a;
    const Eigen::Matrix3d yaw =
        Eigen::AngleAxisd(0.01 * s, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    b.T_world_camera.linear() = yaw * b.T_world_camera.linear();
    b.T_world_camera.translation() = yaw * (1.0 + 0.01 * s) * b.T_world_camera.translation();
    drifting.push_back(b);
  }
  WriteTumTrajectory(out / "estimate_noisy.txt", noisy);
  WriteTumTrajectory(out / "estimate_drifting.txt", drifting);

  EvaluationOptions options;
  const std::vector<EstimateEvaluation> evaluations = {
      EvaluateEstimate(ground_truth, noisy, "noisy", options),
      EvaluateEstimate(ground_truth, drifting, "drifting", options)};
  std::cout << "2. evaluated two simulated estimates of its camera trajectory "
               "(SLAM runs here as it lands):\n\n"
            << FormatTable(evaluations, options);
  WriteEvaluationPlots(evaluations, options, out / "plots");
  std::cout << "\nsequence, trajectories and plots in " << out.string() << "/\n";
}

}  // namespace

void AddDemoCommand(CLI::App& app) {
  auto args = std::make_shared<DemoArgs>();
  CLI::App* cmd = app.add_subcommand("demo", "run the built-in demo (no dataset, no download)");
  cmd->add_option("--out", args->out, "output folder")->capture_default_str();
  cmd->add_option("--seed", args->seed, "random seed")->capture_default_str();
  cmd->callback([args] { RunDemo(*args); });
}

}  // namespace sdoslam
