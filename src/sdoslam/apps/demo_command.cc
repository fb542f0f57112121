#include "sdoslam/apps/demo_command.h"

#include <fmt/format.h>

#include <iostream>
#include <memory>
#include <random>

#include "sdoslam/eval/report.h"
#include "sdoslam/io/trajectory.h"

namespace sdoslam {
namespace {

struct DemoArgs {
  std::string out = "sdoslam_demo";
  unsigned seed = 1;
};

// A TUM-like hand-held motion (half sphere around a point 1.5 m ahead, 30 Hz, 20 s), and two
// simulated estimates of it: one with white noise only, one that also drifts in scale and yaw.
// Until the SLAM pipeline exists, this is what the demo can honestly show: the evaluation.
void RunDemo(const DemoArgs& args) {
  std::mt19937 rng(args.seed);
  std::normal_distribution<double> noise(0.0, 0.005);
  Trajectory ground_truth, noisy, drifting;
  const Eigen::Vector3d target(0, 0, 1.5);
  for (int k = 0; k < 600; ++k) {
    const double t = 1000.0 + k / 30.0, s = k / 30.0;
    const double azimuth = 0.6 * std::sin(0.25 * s), elevation = 0.3 * std::sin(0.17 * s);
    const Eigen::Vector3d centre =
        target - 1.5 * Eigen::Vector3d(std::sin(azimuth) * std::cos(elevation), std::sin(elevation),
                                       std::cos(azimuth) * std::cos(elevation));
    const Eigen::Vector3d z = (target - centre).normalized();
    const Eigen::Vector3d x = Eigen::Vector3d::UnitY().cross(z).normalized();
    StampedPose pose;
    pose.timestamp = t;
    pose.T_world_camera.linear() << x, z.cross(x), z;
    pose.T_world_camera.translation() = centre;
    ground_truth.push_back(pose);

    StampedPose a = pose;
    a.T_world_camera.translation() += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    noisy.push_back(a);
    StampedPose b = a;
    const Eigen::Matrix3d yaw_drift = Eigen::AngleAxisd(0.002 * s, Eigen::Vector3d::UnitY()).toRotationMatrix();
    b.T_world_camera.linear() = yaw_drift * b.T_world_camera.linear();
    b.T_world_camera.translation() = yaw_drift * (1.0 + 0.002 * s) * b.T_world_camera.translation();
    drifting.push_back(b);
  }
  const std::filesystem::path out = args.out;
  WriteTumTrajectory(out / "groundtruth.txt", ground_truth);
  WriteTumTrajectory(out / "estimate_noisy.txt", noisy);
  WriteTumTrajectory(out / "estimate_drifting.txt", drifting);

  EvaluationOptions options;
  const std::vector<EstimateEvaluation> evaluations = {
      EvaluateEstimate(ground_truth, noisy, "noisy", options),
      EvaluateEstimate(ground_truth, drifting, "drifting", options)};
  std::cout << "sdoslam demo: evaluation of two simulated estimates of a 20 s half-sphere motion\n"
            << "(the synthetic sequence -> SLAM -> evaluation demo replaces this as it lands)\n\n"
            << FormatTable(evaluations, options);
  WriteEvaluationPlots(evaluations, options, out / "plots");
  std::cout << "\ntrajectories and plots in " << out.string() << "/\n";
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
