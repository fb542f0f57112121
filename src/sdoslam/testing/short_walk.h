#pragma once

#include <filesystem>

#include "sdoslam/synth/sequence.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam::testing {

// A short synthetic sequence with people walking (walking_xyz), written to dir/walk, for tests
// of the pipeline's stages. The test links sdoslam_synth.
inline std::filesystem::path WriteShortWalk(const TempDir& dir, int frames) {
  synth::SynthOptions options;
  options.scenario = "walking_xyz";
  options.frames = frames;
  const auto sequence = dir / "walk";
  synth::WriteSequence(options, sequence, /*overwrite=*/true);
  return sequence;
}

}  // namespace sdoslam::testing
