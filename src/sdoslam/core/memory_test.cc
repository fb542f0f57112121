#include "sdoslam/core/memory.h"

#include <gtest/gtest.h>

#include <cstring>
#include <memory>

namespace sdoslam {
namespace {

TEST(ResidentBytes, GrowsWhenMemoryIsTouched) {
  const size_t before = ResidentBytes();
  ASSERT_GT(before, 0u);
  constexpr size_t kSize = 64 << 20;
  auto block = std::make_unique<char[]>(kSize);
  std::memset(block.get(), 1, kSize);  // touched pages become resident
  const size_t after = ResidentBytes();
  EXPECT_GT(after, before + kSize / 2);
  EXPECT_EQ(block[kSize - 1], 1);
}

// The peak remembers a block that is gone again, and a reset forgets it: `sdoslam bench` relies
// on both to give each run in one process its own peak.
TEST(PeakResidentBytes, KeepsAFreedBlockUntilReset) {
  if (!ResetPeakResidentBytes()) GTEST_SKIP() << "this kernel cannot reset the peak";
  const size_t before = ResidentBytes();
  constexpr size_t kSize = 64 << 20;
  {
    auto block = std::make_unique<char[]>(kSize);  // this large: its own mapping, unmapped on free
    std::memset(block.get(), 1, kSize);
    EXPECT_EQ(block[kSize - 1], 1);
  }
  ASSERT_LT(ResidentBytes(), before + kSize / 2) << "the block was not given back";
  EXPECT_GT(PeakResidentBytes(), before + kSize / 2);
  ASSERT_TRUE(ResetPeakResidentBytes());
  EXPECT_LT(PeakResidentBytes(), before + kSize / 2);
  EXPECT_GE(PeakResidentBytes() + (1 << 20), ResidentBytes());
}

}  // namespace
}  // namespace sdoslam
