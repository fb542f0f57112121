// detections.json for `dynamic.detector.backend: file`.
#include "fuzz_util.h"
#include "sdoslam/core/error.h"
#include "sdoslam/dynamic/detector.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = sdoslam::fuzz::WriteInput("detections.json", sdoslam::fuzz::AsText(data, size));
  try {
    sdoslam::FileDetector detector(path);
  } catch (const sdoslam::Error&) {
  }
  return 0;
}
