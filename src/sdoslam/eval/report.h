#pragma once

#include <array>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "sdoslam/eval/metrics.h"

namespace sdoslam {

struct EvaluationOptions {
  AteOptions ate;
  RteOptions rte;  // its max_time_difference, time_offset and scale are taken from `ate`
  // Plane of the top-view plot: "xy", "xz", "yz", or "auto" (the two axes along which the
  // ground truth extends most).
  std::string plane = "auto";
  void Check() const;
};

// Everything measured for one estimated trajectory.
struct EstimateEvaluation {
  std::string label;
  size_t estimate_poses = 0;
  size_t ground_truth_poses = 0;
  AteResult ate;
  std::optional<RteResult> rte;  // absent when the run is too short for the delta
  std::string rte_note;          // why it is absent
};

EstimateEvaluation EvaluateEstimate(const Trajectory& ground_truth, const Trajectory& estimate,
                                    const std::string& label, const EvaluationOptions& options);

// A fixed-width table, one row per estimate: ATE statistics and RTE RMSEs.
std::string FormatTable(const std::vector<EstimateEvaluation>& evaluations,
                        const EvaluationOptions& options);

nlohmann::json ToJson(const std::vector<EstimateEvaluation>& evaluations,
                      const EvaluationOptions& options);

// Writes, for each estimate, `<label>_top.{png,svg}` (ground truth, aligned estimate, error
// segments) and one `ate_over_time.{png,svg}` with all estimates. Returns the files written, in
// that order (each estimate's .png then .svg, in the order of `evaluations`).
std::vector<std::filesystem::path> WriteEvaluationPlots(
    const std::vector<EstimateEvaluation>& evaluations, const EvaluationOptions& options,
    const std::filesystem::path& folder);

// Writes, for each estimate, `<label>_ate_over_time.{png,svg}`: its translation error per pose
// against time, on its own scale (in the plot of all estimates, one run that loses track flattens
// the others' lines into the axis). Colours match WriteEvaluationPlots'. Returns the files
// written: each estimate's .png then .svg, in the order of `evaluations`.
std::vector<std::filesystem::path> WriteErrorOverTimePlots(
    const std::vector<EstimateEvaluation>& evaluations, const std::filesystem::path& folder);

// The two axes (0 x, 1 y, 2 z) of a top view of `points`: those of `plane` ("xy", "xz", "yz"),
// or for "auto" the two along which the points extend most.
std::array<int, 2> PlaneAxes(const std::string& plane, const std::vector<Eigen::Vector3d>& points);

// The plots' k-th colour (0xRRGGBB), repeating after six.
unsigned PlotColour(size_t k);

}  // namespace sdoslam
