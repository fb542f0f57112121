#include "sdoslam/core/memory.h"

#include <gtest/gtest.h>
#include <sys/resource.h>

#include <cstring>
#include <iostream>
#include <memory>
#include <vector>

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

long MinorPageFaults() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_minflt;
}

// One frame's worth of image buffers: six 2 MB images allocated, written and freed together.
// Returns the page faults it took.
long FaultsOfOneFrame() {
  constexpr size_t kSize = 2 << 20;
  const long before = MinorPageFaults();
  std::vector<std::unique_ptr<char[]>> images;
  for (int i = 0; i < 6; ++i) {
    images.emplace_back(new char[kSize]);
    std::memset(images.back().get(), i + 1, kSize);
  }
  const long faults = MinorPageFaults() - before;
  EXPECT_EQ(images[3][kSize / 2], 4);
  return faults;
}

// Each frame allocates and frees its images. Kept by the allocator, the next frame's images reuse
// pages already mapped. By default glibc gives them back (12 MB freed at once is more than its
// trim threshold, which follows the largest block freed: 4 MB here), and every page faults again
// at the next frame: about 3,000 faults a frame.
TEST(KeepImageBuffersForReuse, TheNextFramesImagesTakeNoPageFaults) {
  FaultsOfOneFrame();
  const long default_faults = FaultsOfOneFrame();
  if (!KeepImageBuffersForReuse()) GTEST_SKIP() << "this allocator has no such settings";
  FaultsOfOneFrame();  // lands in the heap and grows it
  const long kept_faults = FaultsOfOneFrame();
  std::cout << "page faults of a frame's images: " << default_faults << " by default, "
            << kept_faults << " kept\n";
  EXPECT_GE(default_faults, 1000);
  EXPECT_LE(kept_faults, 50);
}

}  // namespace
}  // namespace sdoslam
