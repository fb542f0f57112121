#include "sdoslam/matching/best_two.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

namespace sdoslam {
namespace {

TEST(BestTwo, KeepsTheTwoNearestAndTheFirstOfATie) {
  BestTwo nearest;
  EXPECT_FALSE(nearest.found());
  nearest.Add(50, 0);
  nearest.Add(30, 1);
  nearest.Add(40, 2);
  nearest.Add(30, 3);  // ties the best: it becomes the second, the first met stays the best
  nearest.Add(60, 4);
  EXPECT_TRUE(nearest.found());
  EXPECT_EQ(nearest.best, 30);
  EXPECT_EQ(nearest.best_index, 1);
  EXPECT_EQ(nearest.second, 30);
  EXPECT_EQ(nearest.second_index, 3);
}

TEST(BestTwo, NoCandidateOrOnlyTheLargestDistanceFindsNothing) {
  BestTwo nearest;
  EXPECT_EQ(nearest.best, 256);
  EXPECT_EQ(nearest.second, 256);
  nearest.Add(256, 7);  // every bit differs
  EXPECT_FALSE(nearest.found());
  nearest.Add(12, 8);
  EXPECT_EQ(nearest.best_index, 8);
  EXPECT_EQ(nearest.second, 256);  // a single candidate has no second
  EXPECT_EQ(nearest.second_index, -1);
}

TEST(BestTwo, RatioTestRejectsUnclearWinners) {
  BestTwo nearest;
  nearest.Add(40, 0);
  nearest.Add(30, 1);
  EXPECT_TRUE(nearest.Ambiguous(0.7));    // 30 > 0.7 × 40 = 28
  EXPECT_FALSE(nearest.Ambiguous(0.8));   // 30 <= 32
  EXPECT_FALSE(nearest.Ambiguous(0.75));  // equal to ratio × second is clear enough
  BestTwo alone;
  alone.Add(90, 0);
  EXPECT_FALSE(alone.Ambiguous(0.7));  // against 256: 90 <= 179.2
}

// The loop it replaced, as it was written in the searches, on random distances: same best,
// second and indices.
TEST(BestTwo, SameAsTheLoopItReplaced) {
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> distance(0, 256), count(0, 12);
  for (int trial = 0; trial < 2000; ++trial) {
    std::vector<int> d(static_cast<size_t>(count(rng)));
    for (int& x : d) x = distance(rng) % (trial % 2 == 0 ? 257 : 20);  // many ties in half
    int best = 256, second = 256, best_index = -1, second_index = -1;
    BestTwo nearest;
    for (size_t j = 0; j < d.size(); ++j) {
      if (d[j] < best) {
        second = best;
        second_index = best_index;
        best = d[j];
        best_index = static_cast<int>(j);
      } else if (d[j] < second) {
        second = d[j];
        second_index = static_cast<int>(j);
      }
      nearest.Add(d[j], static_cast<int>(j));
    }
    ASSERT_EQ(nearest.best, best);
    ASSERT_EQ(nearest.second, second);
    ASSERT_EQ(nearest.best_index, best_index);
    ASSERT_EQ(nearest.second_index, second_index);
  }
}

}  // namespace
}  // namespace sdoslam
