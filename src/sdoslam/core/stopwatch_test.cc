#include "sdoslam/core/stopwatch.h"

#include <gtest/gtest.h>

#include <cmath>
#include <thread>

namespace sdoslam {
namespace {

// A sleeping thread uses no CPU; a computing one uses about its wall time. Wall time counts
// both.
TEST(Stopwatch, ThreadCpuTimeCountsWorkNotWaiting) {
  const StageClock sleeping;
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_GE(sleeping.WallMs(), 100.0);
  EXPECT_LT(sleeping.CpuMs(), 20.0);

  const StageClock computing;
  volatile double sink = 0;
  while (computing.WallMs() < 100.0) {
    for (int i = 0; i < 1000; ++i) sink = sink + std::sqrt(static_cast<double>(i));
  }
  const double used = computing.CpuMs();
  // Another process may take the core for part of the 100 ms; most of it is this thread's.
  EXPECT_GT(used, 30.0);
  EXPECT_LE(used, computing.WallMs() + 1.0);
}

}  // namespace
}  // namespace sdoslam
