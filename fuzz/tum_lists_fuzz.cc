// rgb.txt and depth.txt of a TUM folder (the input holds both, split at "\n----\n"), opened as
// `run --dataset` opens them: parsing, association, checks that listed images exist.
#include "fuzz_util.h"
#include "sdoslam/core/error.h"
#include "sdoslam/io/tum_dataset.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace sdoslam::fuzz;
  const auto [rgb, depth] = SplitInTwo(AsText(data, size));
  WriteInput("tum/rgb.txt", rgb);
  WriteInput("tum/depth.txt", depth);
  WriteInput("tum/rgb/1.png", "x");  // listed images must exist; they are not decoded here
  WriteInput("tum/depth/1.png", "x");
  sdoslam::CameraOptions camera;
  camera.width = 16;
  camera.height = 12;
  camera.fx = camera.fy = 20;
  camera.cx = 8;
  camera.cy = 6;
  try {
    sdoslam::TumDataset dataset(ScratchDir() / "tum", camera);
  } catch (const sdoslam::Error&) {
  }
  return 0;
}
