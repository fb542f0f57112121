// Loop closing end to end lives in slam/system_test.cc (the long loop); here, its options.
#include "sdoslam/loop/loop_closer.h"

#include <gtest/gtest.h>

#include "sdoslam/core/error.h"

namespace sdoslam {
namespace {

TEST(LoopClosingOptionsTest, RejectsImpossibleSettings) {
  LoopClosingOptions o;
  EXPECT_NO_THROW(o.Check());
  o.min_projected_inliers = o.min_inliers - 1;
  EXPECT_THROW(o.Check(), Error);
  o = LoopClosingOptions{};
  o.min_matches = 2;
  EXPECT_THROW(o.Check(), Error);
  o = LoopClosingOptions{};
  o.verify_neighbours = -1;
  EXPECT_THROW(o.Check(), Error);
}

}  // namespace
}  // namespace sdoslam
