#include "sdoslam/core/timestamps.h"

#include <gtest/gtest.h>

namespace sdoslam {
namespace {

using Pairs = std::vector<std::pair<size_t, size_t>>;

TEST(AssociateTimestamps, PicksClosestAndUsesEachElementOnce) {
  // second[0] is closest to both first[0] and first[1]; the closer pair (first[1]) wins and
  // first[0] falls back to nothing because second[1] is too far from it.
  const std::vector<double> first = {1.000, 1.012, 2.000};
  const std::vector<double> second = {1.010, 1.040, 2.005};
  EXPECT_EQ(AssociateTimestamps(first, second, 0.02), (Pairs{{1, 0}, {2, 2}}));
}

TEST(AssociateTimestamps, ToleranceIsStrictAndOffsetShiftsTheSecond) {
  const std::vector<double> first = {10.0, 11.0};
  const std::vector<double> second = {10.02, 10.5};
  EXPECT_TRUE(AssociateTimestamps({10.0}, {10.0 + 0.0200001}, 0.02).empty());
  EXPECT_EQ(AssociateTimestamps(first, second, 0.021), (Pairs{{0, 0}}));
  EXPECT_EQ(AssociateTimestamps(first, second, 0.021, 0.5), (Pairs{{1, 1}}));
}

TEST(AssociateTimestamps, UnsortedSecondAndEmptyInputs) {
  EXPECT_EQ(AssociateTimestamps({1.0, 2.0, 3.0}, {3.001, 1.001, 2.001}, 0.01),
            (Pairs{{0, 1}, {1, 2}, {2, 0}}));
  EXPECT_TRUE(AssociateTimestamps({}, {1.0}, 0.02).empty());
  EXPECT_TRUE(AssociateTimestamps({1.0}, {}, 0.02).empty());
}

TEST(AssociateTimestamps, MatchesBruteForceGreedyOnRandomStreams) {
  // Reference: the O(n·m) procedure of the TUM associate tool, written out plainly.
  std::srand(7);
  std::vector<double> a, b;
  double ta = 0, tb = 0.005;
  for (int k = 0; k < 300; ++k) {
    ta += 0.02 + 0.03 * (std::rand() / double(RAND_MAX));
    tb += 0.02 + 0.03 * (std::rand() / double(RAND_MAX));
    a.push_back(ta);
    b.push_back(tb);
  }
  std::vector<std::tuple<double, size_t, size_t>> all;
  for (size_t i = 0; i < a.size(); ++i)
    for (size_t j = 0; j < b.size(); ++j)
      if (std::abs(a[i] - b[j]) < 0.02) all.emplace_back(std::abs(a[i] - b[j]), i, j);
  std::sort(all.begin(), all.end());
  std::vector<bool> ua(a.size()), ub(b.size());
  Pairs expected;
  for (auto [d, i, j] : all) {
    if (ua[i] || ub[j]) continue;
    ua[i] = ub[j] = true;
    expected.emplace_back(i, j);
  }
  std::sort(expected.begin(), expected.end());
  ASSERT_GT(expected.size(), 50u);
  EXPECT_EQ(AssociateTimestamps(a, b, 0.02), expected);
}

}  // namespace
}  // namespace sdoslam
