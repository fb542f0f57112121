#include "sdoslam/eval/report.h"

#include <gtest/gtest.h>

#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

Trajectory Line(double speed, int n) {
  Trajectory t;
  for (int k = 0; k < n; ++k) {
    StampedPose p;
    p.timestamp = k / 30.0;
    p.T_world_camera.translation() =
        Eigen::Vector3d(speed * p.timestamp, 0.1 * std::sin(p.timestamp), 0);
    t.push_back(p);
  }
  return t;
}

TEST(Report, TableJsonAndPlotsCarryTheNumbers) {
  testing::TempDir dir;
  const Trajectory gt = Line(1.0, 90);
  EvaluationOptions options;
  std::vector<EstimateEvaluation> evals = {EvaluateEstimate(gt, gt, "perfect", options),
                                           EvaluateEstimate(gt, Line(1.1, 90), "drift", options)};
  EXPECT_LT(evals[0].ate.translation.rmse, 1e-12);
  EXPECT_GT(evals[1].ate.translation.rmse, 0.01);
  ASSERT_TRUE(evals[1].rte.has_value());
  EXPECT_NEAR(evals[1].rte->translation.rmse, 0.1, 1e-9);

  const std::string table = FormatTable(evals, options);
  EXPECT_NE(table.find("perfect"), std::string::npos);
  EXPECT_NE(table.find("0.1000"), std::string::npos) << table;

  const nlohmann::json j = ToJson(evals, options);
  EXPECT_EQ(j["estimates"].size(), 2u);
  EXPECT_EQ(j["estimates"][1]["label"], "drift");
  EXPECT_NEAR(j["estimates"][1]["rte"]["translation"]["rmse"].get<double>(), 0.1, 1e-9);
  EXPECT_EQ(j["estimates"][0]["matched_poses"], 90);
  EXPECT_EQ(j["alignment"], "se3");

  const auto files = WriteEvaluationPlots(evals, options, dir.path());
  EXPECT_EQ(files.size(), 6u);
  for (const auto& f : files) EXPECT_GT(std::filesystem::file_size(f), 100u) << f;

  const auto per_run = WriteErrorOverTimePlots(evals, dir / "per_run");
  ASSERT_EQ(per_run.size(), 4u);
  EXPECT_EQ(per_run[0], dir / "per_run" / "perfect_ate_over_time.png");
  EXPECT_EQ(per_run[3], dir / "per_run" / "drift_ate_over_time.svg");
  EXPECT_NE(testing::ReadText(per_run[3]).find("drift: error over time"), std::string::npos);
}

TEST(Report, ShortRunStillGivesAteAndExplainsMissingRte) {
  const Trajectory gt = Line(1.0, 20);
  const EstimateEvaluation e = EvaluateEstimate(gt, gt, "short", {});
  EXPECT_FALSE(e.rte.has_value());
  EXPECT_NE(e.rte_note.find("too short"), std::string::npos);
  EXPECT_NE(FormatTable({e}, {}).find("n/a"), std::string::npos);
}

}  // namespace
}  // namespace sdoslam
