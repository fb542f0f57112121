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

}  // namespace
}  // namespace sdoslam
