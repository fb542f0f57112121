#include "sdoslam/optim/ransac.h"

#include <gtest/gtest.h>

#include <cmath>
#include <optional>
#include <random>
#include <vector>

namespace sdoslam {
namespace {

// A toy problem with a known answer: the line y = a·x + b through 2-D points, a fifth of them
// outliers. Minimal samples of two points; a sample of two equal x is degenerate.
struct LineProblem {
  using Model = std::pair<double, double>;  // slope, intercept
  using Score = int;                        // inliers

  std::vector<double> x, y;
  std::mt19937 random{7};
  int max_iterations = 200;
  bool adaptive = true;
  int improved = 0;  // Improve calls

  std::optional<Model> Hypothesis() {
    const size_t i = random() % x.size(), j = random() % x.size();
    if (x[i] == x[j]) return std::nullopt;
    const double slope = (y[j] - y[i]) / (x[j] - x[i]);
    return Model{slope, y[i] - slope * x[i]};
  }
  int Evaluate(const Model& line) const {
    int inliers = 0;
    for (size_t k = 0; k < x.size(); ++k)
      inliers += std::abs(line.first * x[k] + line.second - y[k]) < 0.05;
    return inliers;
  }
  static bool Better(int inliers, int best) { return inliers > best; }
  void Improve(Model*, int*) { ++improved; }
  int Iterations(int best) const {
    if (!adaptive || best <= 0) return max_iterations;
    const double w = static_cast<double>(best) / static_cast<double>(x.size());
    return std::min(max_iterations,
                    static_cast<int>(std::ceil(std::log(1 - 0.99) / std::log(1 - w * w))));
  }
  static int Worst() { return -1; }
};

LineProblem NoisyLine(int points) {
  LineProblem p;
  std::mt19937 random(3);
  std::uniform_real_distribution<double> uniform(-5, 5), noise(-0.01, 0.01);
  for (int i = 0; i < points; ++i) {
    const double x = uniform(random);
    p.x.push_back(x);
    p.y.push_back(i % 5 == 0 ? uniform(random) : 2.0 * x - 1.0 + noise(random));
  }
  return p;
}

TEST(Ransac, FindsTheLineThroughTheInliersAndStopsOnceConfident) {
  LineProblem problem = NoisyLine(100);
  const RansacOutcome<LineProblem::Model, int> outcome = Ransac(problem);
  ASSERT_TRUE(outcome.model.has_value());
  EXPECT_NEAR(outcome.model->first, 2.0, 0.02);
  EXPECT_NEAR(outcome.model->second, -1.0, 0.05);
  EXPECT_GE(outcome.score, 78);  // the 80 inliers, give or take the noise's edge
  EXPECT_EQ(outcome.score, problem.Evaluate(*outcome.model));
  // With 80 % inliers, 99 % confidence needs 5 samples of two: far fewer than the 200 allowed.
  EXPECT_LT(outcome.iterations, 20);
  EXPECT_GE(problem.improved, 1);  // every new best is improved
}

TEST(Ransac, DrawsTheFixedCountWhenNotAdaptiveAndCountsDegenerateSamples) {
  LineProblem problem = NoisyLine(100);
  problem.adaptive = false;
  problem.max_iterations = 37;
  EXPECT_EQ(Ransac(problem).iterations, 37);

  LineProblem degenerate;  // every sample degenerate: all x equal
  degenerate.x.assign(10, 1.0);
  degenerate.y.assign(10, 0.0);
  degenerate.max_iterations = 12;
  const RansacOutcome<LineProblem::Model, int> outcome = Ransac(degenerate);
  EXPECT_FALSE(outcome.model.has_value());
  EXPECT_EQ(outcome.score, LineProblem::Worst());
  EXPECT_EQ(outcome.iterations, 12);
  EXPECT_EQ(degenerate.improved, 0);
}

TEST(Ransac, TheSameDrawsGiveTheSameModel) {
  LineProblem first = NoisyLine(60), second = NoisyLine(60);
  const auto a = Ransac(first), b = Ransac(second);
  ASSERT_TRUE(a.model && b.model);
  EXPECT_EQ(*a.model, *b.model);
  EXPECT_EQ(a.iterations, b.iterations);
}

}  // namespace
}  // namespace sdoslam
