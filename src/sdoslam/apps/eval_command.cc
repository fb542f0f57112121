#include "sdoslam/apps/eval_command.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <iostream>
#include <memory>
#include <set>

#include "sdoslam/core/atomic_file.h"
#include "sdoslam/core/error.h"
#include "sdoslam/core/regular_file.h"
#include "sdoslam/eval/report.h"
#include "sdoslam/io/result_set.h"

namespace sdoslam {
namespace {

struct EvalArgs {
  std::string ground_truth;
  std::vector<std::string> estimates;
  std::vector<std::string> labels;
  std::string alignment = "se3";
  double max_time_difference = 0.02;
  double time_offset = 0.0;
  double delta = 1.0;
  std::string delta_unit = "s";
  std::string rte_pairing = "tum";
  std::string json;
  std::string plot_dir = "eval_plots";
  bool no_plots = false;
  std::string plane = "auto";
};

Trajectory ReadNonEmpty(const std::string& path) {
  RejectNonRegularFile(path);  // before its manifest is consulted, which would hash it
  // A file of an sdoslam result set must match its manifest (not a half-replaced set).
  if (const auto manifest = VerifyResultFile(path); manifest && manifest->status != "complete") {
    std::cerr << fmt::format("note: {} is from an interrupted run ({} of {} frames)\n", path,
                             manifest->info.value("frames_processed", size_t{0}),
                             manifest->info.value("frames_requested", size_t{0}));
  }
  Trajectory t = ReadTumTrajectory(path);
  if (t.empty()) throw Error(path + ": no poses in this trajectory file");
  return t;
}

void RunEval(const EvalArgs& args) {
  EvaluationOptions options;
  options.ate.alignment = ParseAlignmentMode(args.alignment);
  options.ate.max_time_difference = args.max_time_difference;
  options.ate.time_offset = args.time_offset;
  options.rte.delta = args.delta;
  options.rte.unit = ParseDeltaUnit(args.delta_unit);
  options.rte.pairing = ParseRtePairing(args.rte_pairing);
  options.plane = args.plane;
  options.Check();
  if (!args.labels.empty() && args.labels.size() != args.estimates.size()) {
    throw Error(fmt::format("--label given {} times for {} --est files", args.labels.size(),
                            args.estimates.size()));
  }

  const Trajectory ground_truth = ReadNonEmpty(args.ground_truth);
  std::vector<EstimateEvaluation> evaluations;
  std::set<std::string> used_labels;
  for (size_t k = 0; k < args.estimates.size(); ++k) {
    std::string label = args.labels.empty()
                            ? std::filesystem::path(args.estimates[k]).stem().string()
                            : args.labels[k];
    for (int n = 2; used_labels.count(label); ++n) label = fmt::format("{}_{}", label, n);
    used_labels.insert(label);
    const Trajectory estimate = ReadNonEmpty(args.estimates[k]);
    try {
      evaluations.push_back(EvaluateEstimate(ground_truth, estimate, label, options));
    } catch (const Error& e) {
      throw Error(args.estimates[k] + ": " + e.what());
    }
  }

  std::cout << FormatTable(evaluations, options);
  if (!args.json.empty()) {
    nlohmann::json j = ToJson(evaluations, options);
    j["ground_truth"] = args.ground_truth;
    for (size_t k = 0; k < args.estimates.size(); ++k)
      j["estimates"][k]["file"] = args.estimates[k];
    WriteFileAtomically(args.json, [&](std::ostream& out) { out << j.dump(2) << '\n'; });
    std::cout << "wrote " << args.json << '\n';
  }
  if (!args.no_plots) {
    const auto files = WriteEvaluationPlots(evaluations, options, args.plot_dir);
    std::cout << "wrote " << files.size() << " plots to " << args.plot_dir << "/\n";
  }
}

}  // namespace

void AddEvalCommand(CLI::App& app) {
  auto args = std::make_shared<EvalArgs>();
  CLI::App* cmd = app.add_subcommand(
      "eval", "ATE and RTE of estimated trajectories against ground truth (TUM format)");
  cmd->add_option("--gt", args->ground_truth, "ground-truth trajectory (TUM format)")->required();
  cmd->add_option("--est", args->estimates,
                  "estimated trajectory (TUM format); repeat to compare several")
      ->required();
  cmd->add_option("--label", args->labels, "names for the estimates, in --est order");
  cmd->add_option("--align", args->alignment, "alignment: se3 (RGB-D), sim3 (monocular), none")
      ->check(CLI::IsMember({"se3", "sim3", "none"}))
      ->capture_default_str();
  cmd->add_option("--max-time-diff", args->max_time_difference,
                  "largest timestamp difference for a match, seconds")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--offset", args->time_offset, "added to the estimate's timestamps, seconds")
      ->capture_default_str();
  cmd->add_option("--delta", args->delta, "RTE interval (the paper: 1 s)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--delta-unit", args->delta_unit, "unit of --delta: s or frames")
      ->check(CLI::IsMember({"s", "frames"}))
      ->capture_default_str();
  cmd->add_option("--rte-pairing", args->rte_pairing,
                  "tum: pair poses as TUM's evaluate_rpe.py --fixed_delta (what papers report); "
                  "strict: only poses within half a frame of t + delta")
      ->check(CLI::IsMember({"tum", "strict"}))
      ->capture_default_str();
  cmd->add_option("--json", args->json, "also write the results as JSON to this file");
  cmd->add_option("--plot-dir", args->plot_dir, "folder for the PNG/SVG plots")
      ->capture_default_str();
  cmd->add_flag("--no-plots", args->no_plots, "write no plots");
  cmd->add_option("--plane", args->plane, "top-view plane: auto, xy, xz, yz")
      ->check(CLI::IsMember({"auto", "xy", "xz", "yz"}))
      ->capture_default_str();
  cmd->callback([args] { RunEval(*args); });
}

}  // namespace sdoslam
