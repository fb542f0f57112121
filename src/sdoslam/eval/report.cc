#include "sdoslam/eval/report.h"

#include <fmt/format.h>

#include <algorithm>

#include "sdoslam/core/error.h"
#include "sdoslam/eval/plot.h"

namespace sdoslam {

unsigned PlotColour(size_t k) {
  constexpr unsigned kPalette[] = {0xd62728, 0x1f77b4, 0x2ca02c, 0xff7f0e, 0x9467bd, 0x8c564b};
  return kPalette[k % std::size(kPalette)];
}

std::array<int, 2> PlaneAxes(const std::string& plane, const std::vector<Eigen::Vector3d>& gt) {
  if (plane == "xy") return {0, 1};
  if (plane == "xz") return {0, 2};
  if (plane == "yz") return {1, 2};
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  for (const auto& p : gt) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const Eigen::Vector3d extent = hi - lo;
  int smallest = 0;
  extent.minCoeff(&smallest);
  if (smallest == 0) return {1, 2};
  if (smallest == 1) return {0, 2};
  return {0, 1};
}

namespace {

std::string FileSafe(const std::string& label) {
  std::string s;
  for (char c : label)
    s += (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '.') ? c : '_';
  return s.empty() ? "estimate" : s;
}

nlohmann::json StatsJson(const ErrorStats& s) {
  return {{"rmse", s.rmse}, {"mean", s.mean}, {"median", s.median}, {"std", s.std},
          {"min", s.min},   {"max", s.max},   {"count", s.count}};
}

}  // namespace

void EvaluationOptions::Check() const {
  ate.Check();
  RteOptions r = rte;
  r.max_time_difference = ate.max_time_difference;
  r.time_offset = ate.time_offset;
  r.Check();
  if (plane != "auto" && plane != "xy" && plane != "xz" && plane != "yz") {
    throw Error("unknown plot plane '" + plane + "' (use auto, xy, xz or yz)");
  }
}

EstimateEvaluation EvaluateEstimate(const Trajectory& ground_truth, const Trajectory& estimate,
                                    const std::string& label, const EvaluationOptions& options) {
  options.Check();
  EstimateEvaluation e;
  e.label = label;
  e.estimate_poses = estimate.size();
  e.ground_truth_poses = ground_truth.size();
  e.ate = ComputeAte(ground_truth, estimate, options.ate);
  RteOptions rte = options.rte;
  rte.max_time_difference = options.ate.max_time_difference;
  rte.time_offset = options.ate.time_offset;
  rte.scale = e.ate.alignment.scale;
  try {
    e.rte = ComputeRte(ground_truth, estimate, rte);
  } catch (const Error& error) {
    e.rte_note = error.what();
  }
  return e;
}

std::string FormatTable(const std::vector<EstimateEvaluation>& evaluations,
                        const EvaluationOptions& options) {
  size_t label_width = 8;
  for (const auto& e : evaluations) label_width = std::max(label_width, e.label.size());
  const std::string delta =
      fmt::format("{:g}{}", options.rte.delta, options.rte.unit == DeltaUnit::kFrames ? "f" : "s");
  std::string out = fmt::format(
      "ATE (align {}) in metres; RTE over {} (trans m / rot deg)\n{:<{}} {:>7} {:>9} {:>9} {:>9} "
      "{:>9} {:>9} {:>9} {:>10} {:>10} {:>6}\n",
      ToString(options.ate.alignment), delta, "estimate", label_width, "matched", "ATE rmse",
      "mean", "median", "std", "min", "max", "RTE trans", "RTE rot", "pairs");
  for (const auto& e : evaluations) {
    const ErrorStats& s = e.ate.translation;
    out +=
        fmt::format("{:<{}} {:>7} {:>9.4f} {:>9.4f} {:>9.4f} {:>9.4f} {:>9.4f} {:>9.4f} ", e.label,
                    label_width, s.count, s.rmse, s.mean, s.median, s.std, s.min, s.max);
    if (e.rte) {
      out += fmt::format("{:>10.4f} {:>10.3f} {:>6}\n", e.rte->translation.rmse,
                         e.rte->rotation.rmse, e.rte->translation.count);
    } else {
      out += fmt::format("{:>10} {:>10} {:>6}\n", "n/a", "n/a", 0);
    }
  }
  for (const auto& e : evaluations) {
    if (!e.rte) out += fmt::format("note: {}: no RTE: {}\n", e.label, e.rte_note);
    if (e.ate.translation.count < e.estimate_poses) {
      out += fmt::format("note: {}: {} of {} estimated poses have no ground truth within {} s\n",
                         e.label, e.estimate_poses - e.ate.translation.count, e.estimate_poses,
                         options.ate.max_time_difference);
    }
  }
  return out;
}

nlohmann::json ToJson(const std::vector<EstimateEvaluation>& evaluations,
                      const EvaluationOptions& options) {
  nlohmann::json estimates = nlohmann::json::array();
  for (const auto& e : evaluations) {
    const Similarity& a = e.ate.alignment;
    nlohmann::json rotation = nlohmann::json::array();
    for (int r = 0; r < 3; ++r)
      rotation.push_back({a.rotation(r, 0), a.rotation(r, 1), a.rotation(r, 2)});
    nlohmann::json item = {
        {"label", e.label},
        {"estimate_poses", e.estimate_poses},
        {"ground_truth_poses", e.ground_truth_poses},
        {"matched_poses", e.ate.translation.count},
        {"ate", StatsJson(e.ate.translation)},
        {"alignment",
         {{"scale", a.scale},
          {"rotation", rotation},
          {"translation", {a.translation.x(), a.translation.y(), a.translation.z()}}}}};
    if (e.rte) {
      item["rte"] = {{"translation", StatsJson(e.rte->translation)},
                     {"rotation_deg", StatsJson(e.rte->rotation)}};
    } else {
      item["rte"] = nullptr;
      item["rte_note"] = e.rte_note;
    }
    estimates.push_back(item);
  }
  return {{"units", {{"ate", "m"}, {"rte_translation", "m"}, {"rte_rotation", "deg"}}},
          {"alignment", ToString(options.ate.alignment)},
          {"max_time_difference", options.ate.max_time_difference},
          {"time_offset", options.ate.time_offset},
          {"rte_delta", options.rte.delta},
          {"rte_delta_unit", options.rte.unit == DeltaUnit::kFrames ? "frames" : "s"},
          {"rte_pairing", ToString(options.rte.pairing)},
          {"estimates", estimates}};
}

std::vector<std::filesystem::path> WriteEvaluationPlots(
    const std::vector<EstimateEvaluation>& evaluations, const EvaluationOptions& options,
    const std::filesystem::path& folder) {
  std::vector<std::filesystem::path> written;
  if (evaluations.empty()) return written;
  const char* kAxisNames = "xyz";
  Plot over_time{
      "Absolute trajectory error over time", "time since start [s]", "ATE [m]", false, {}};
  const double t0 = evaluations.front().ate.timestamps.front();
  for (size_t k = 0; k < evaluations.size(); ++k) {
    const EstimateEvaluation& e = evaluations[k];
    const unsigned colour = PlotColour(k);
    const auto axes = PlaneAxes(options.plane, e.ate.ground_truth);
    auto project = [&](const Eigen::Vector3d& p) {
      return Eigen::Vector2d(p[axes[0]], p[axes[1]]);
    };
    PlotSeries gt{"ground truth", {}, 0x000000, 1.5, false};
    PlotSeries est{e.label, {}, colour, 1.5, false};
    PlotSeries errors{"error", {}, 0xaaaaaa, 1.0, true};
    const size_t step =
        std::max<size_t>(1, e.ate.ground_truth.size() / 400);  // keep plots readable
    for (size_t i = 0; i < e.ate.ground_truth.size(); ++i) {
      gt.points.push_back(project(e.ate.ground_truth[i]));
      est.points.push_back(project(e.ate.estimate_aligned[i]));
      if (i % step == 0) {
        errors.points.push_back(project(e.ate.ground_truth[i]));
        errors.points.push_back(project(e.ate.estimate_aligned[i]));
      }
    }
    Plot top{fmt::format("{}: top view, ATE RMSE {:.4f} m", e.label, e.ate.translation.rmse),
             fmt::format("{} [m]", kAxisNames[axes[0]]),
             fmt::format("{} [m]", kAxisNames[axes[1]]),
             true,
             {errors, gt, est}};
    for (const char* ext : {".png", ".svg"}) {
      const auto path = folder / (FileSafe(e.label) + "_top" + ext);
      SavePlot(top, path);
      written.push_back(path);
    }
    PlotSeries series{e.label, {}, colour, 1.5, false};
    for (size_t i = 0; i < e.ate.errors.size(); ++i) {
      series.points.emplace_back(e.ate.timestamps[i] - t0, e.ate.errors[i]);
    }
    over_time.series.push_back(series);
  }
  for (const char* ext : {".png", ".svg"}) {
    const auto path = folder / (std::string("ate_over_time") + ext);
    SavePlot(over_time, path);
    written.push_back(path);
  }
  return written;
}

std::vector<std::filesystem::path> WriteErrorOverTimePlots(
    const std::vector<EstimateEvaluation>& evaluations, const std::filesystem::path& folder) {
  std::vector<std::filesystem::path> written;
  for (size_t k = 0; k < evaluations.size(); ++k) {
    const EstimateEvaluation& e = evaluations[k];
    PlotSeries series{"", {}, PlotColour(k), 1.5, false};
    const double t0 = e.ate.timestamps.empty() ? 0.0 : e.ate.timestamps.front();
    for (size_t i = 0; i < e.ate.errors.size(); ++i) {
      series.points.emplace_back(e.ate.timestamps[i] - t0, e.ate.errors[i]);
    }
    const Plot plot{
        fmt::format("{}: error over time, ATE RMSE {:.4f} m", e.label, e.ate.translation.rmse),
        "time since start [s]",
        "ATE [m]",
        false,
        {series}};
    for (const char* ext : {".png", ".svg"}) {
      const auto path = folder / (FileSafe(e.label) + "_ate_over_time" + ext);
      SavePlot(plot, path);
      written.push_back(path);
    }
  }
  return written;
}

}  // namespace sdoslam
