#include "sdoslam/place/place_index.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

namespace sdoslam {
namespace {

// An L1-normalised bag of the given words, equal weights.
BowVector Bag(const std::vector<WordId>& words) {
  BowVector bow;
  for (WordId w : words) bow[w] = 1.0 / static_cast<double>(words.size());
  return bow;
}

std::vector<uint64_t> Ids(const std::vector<PlaceIndex::Candidate>& candidates) {
  std::vector<uint64_t> ids;
  for (const auto& c : candidates) ids.push_back(c.id);
  return ids;
}

TEST(PlaceIndex, QueryKeepsThoseWithAtLeastFourFifthsOfTheMostCommonWordsBestFirst) {
  PlaceIndex index;
  const BowVector query = Bag({0, 1, 2, 3, 4, 5, 6, 7, 8, 9});
  index.Add(10, Bag({0, 1, 2, 3, 4, 5, 6, 7, 8, 9}));          // 10 in common, identical
  index.Add(11, Bag({0, 1, 2, 3, 4, 5, 6, 7, 20, 21}));        // 8 in common: 8 >= 0.8 x 10
  index.Add(12, Bag({0, 1, 2, 3, 4, 5, 6, 30, 31, 32}));       // 7: out
  index.Add(13, Bag({0, 1, 2, 3, 4, 5, 6, 7, 8, 40, 41}));     // 9 in common
  index.Add(14, Bag({50, 51}));                                // none
  index.Add(15, Bag({0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 60, 61}));  // 10 in common, 2 more
  ASSERT_EQ(index.size(), 6u);

  const auto candidates = index.Query(query, 10);
  ASSERT_EQ(Ids(candidates), (std::vector<uint64_t>{10, 15, 13, 11}));
  EXPECT_EQ(candidates[0].common_words, 10);
  EXPECT_DOUBLE_EQ(candidates[0].score, 1.0);
  EXPECT_EQ(candidates[1].common_words, 10);
  EXPECT_NEAR(candidates[1].score, 10.0 / 12.0, 1e-12);  // 1 - 0.5 (10 (1/10 - 1/12) + 2/12)
  EXPECT_EQ(candidates[2].common_words, 9);
  EXPECT_EQ(candidates[3].common_words, 8);
  EXPECT_NEAR(candidates[2].score, 9.0 / 11.0, 1e-12);
  EXPECT_NEAR(candidates[3].score, 0.8, 1e-12);

  EXPECT_EQ(Ids(index.Query(query, 2)), (std::vector<uint64_t>{10, 15}));
  EXPECT_TRUE(index.Query(query, 0).empty());
  EXPECT_TRUE(index.Query(Bag({99}), 5).empty());
  EXPECT_TRUE(index.Query({}, 5).empty());
}

TEST(PlaceIndex, AcceptFilterComesBeforeTheRule) {
  PlaceIndex index;
  const BowVector query = Bag({0, 1, 2, 3, 4, 5, 6, 7, 8, 9});
  index.Add(1, Bag({0, 1, 2, 3, 4, 5, 6, 7, 8, 9}));  // 10 in common: the caller's neighbour
  index.Add(2, Bag({0, 1, 2, 3, 4, 5, 6, 7}));        // 8
  index.Add(3, Bag({0, 1, 2, 3, 4, 5, 6}));           // 7
  index.Add(4, Bag({0, 1, 2, 3, 4, 5}));              // 6
  std::vector<uint64_t> asked;
  const auto candidates = index.Query(query, 10, [&](uint64_t id) {
    asked.push_back(id);
    return id != 1;
  });
  // Without 1 the most is 8: 7 >= 6.4 stays, 6 does not.
  EXPECT_EQ(Ids(candidates), (std::vector<uint64_t>{2, 3}));
  std::sort(asked.begin(), asked.end());
  EXPECT_EQ(asked, (std::vector<uint64_t>{1, 2, 3, 4}));  // once each
  EXPECT_TRUE(index.Query(query, 10, [](uint64_t) { return false; }).empty());
}

TEST(PlaceIndex, EqualScoresAreOrderedById) {
  PlaceIndex index;
  for (uint64_t id : {9u, 3u, 7u}) index.Add(id, Bag({1, 2, 3}));
  EXPECT_EQ(Ids(index.Query(Bag({1, 2, 3}), 10)), (std::vector<uint64_t>{3, 7, 9}));
}

TEST(PlaceIndex, EraseAndReplace) {
  PlaceIndex index;
  index.Add(1, Bag({1, 2, 3}));
  index.Add(2, Bag({1, 2, 3, 4}));
  index.Erase(1);
  index.Erase(1);   // again: nothing
  index.Erase(42);  // unknown: nothing
  EXPECT_EQ(index.size(), 1u);
  EXPECT_FALSE(index.Contains(1));
  EXPECT_EQ(Ids(index.Query(Bag({1, 2, 3}), 10)), (std::vector<uint64_t>{2}));
  // Adding an id again replaces its words: the old ones no longer find it.
  index.Add(2, Bag({7, 8}));
  EXPECT_EQ(index.size(), 1u);
  EXPECT_TRUE(index.Query(Bag({1, 2, 3}), 10).empty());
  EXPECT_EQ(Ids(index.Query(Bag({8}), 10)), (std::vector<uint64_t>{2}));
  ASSERT_NE(index.Find(2), nullptr);
  EXPECT_EQ(*index.Find(2), Bag({7, 8}));
  EXPECT_EQ(index.Find(1), nullptr);
  index.Erase(2);
  EXPECT_EQ(index.size(), 0u);
  EXPECT_TRUE(index.Query(Bag({7, 8}), 10).empty());
}

}  // namespace
}  // namespace sdoslam
