// TUM trajectories and ground truth (eval --gt / --est, groundtruth.txt of a dataset).
#include "fuzz_util.h"
#include "sdoslam/core/error.h"
#include "sdoslam/io/trajectory.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = sdoslam::fuzz::WriteInput("trajectory.txt", sdoslam::fuzz::AsText(data, size));
  try {
    const sdoslam::Trajectory t = sdoslam::ReadTumTrajectory(path);
    if (t.size() >= 2)
      sdoslam::InterpolatePose(t, 0.5 * (t.front().timestamp + t.back().timestamp), 0.1);
  } catch (const sdoslam::Error&) {
    // A named error is the expected outcome for bad input; anything else is a finding.
  }
  return 0;
}
