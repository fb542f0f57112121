#pragma once

#include <chrono>

namespace sdoslam {

// Milliseconds of wall-clock (steady) time since `start`: the unit of every per-stage timing.
inline double MsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

}  // namespace sdoslam
