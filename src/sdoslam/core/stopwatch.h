#pragma once

#include <time.h>

#include <chrono>

namespace sdoslam {

// Milliseconds of wall-clock (steady) time since `start`: the unit of every per-stage timing.
inline double MsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

// CPU time the calling thread has used, in milliseconds. A stage's wall time in a threaded run
// also holds the time the scheduler gave its core to other threads; its CPU time is the work
// it did (threads it hands work to, such as OpenCV's, are not counted).
inline double ThreadCpuMs() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return 1e3 * static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_nsec);
}

// Wall-clock and calling-thread CPU time since construction, for a stage timed both ways.
struct StageClock {
  std::chrono::steady_clock::time_point wall_start = std::chrono::steady_clock::now();
  double cpu_start = ThreadCpuMs();
  double WallMs() const { return MsSince(wall_start); }
  double CpuMs() const { return ThreadCpuMs() - cpu_start; }
};

}  // namespace sdoslam
