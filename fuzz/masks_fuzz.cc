// Mask images as eval-masks, the oracle mode and the file segmenter read them: the PNG header
// check, then decoding as an 8-bit label image.
#include <opencv2/imgcodecs.hpp>

#include "fuzz_util.h"
#include "sdoslam/core/error.h"
#include "sdoslam/io/image_header.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = sdoslam::fuzz::WriteInput("mask.png", sdoslam::fuzz::AsText(data, size));
  try {
    const sdoslam::PngHeader header = sdoslam::ReadPngHeader(path);
    // As the readers do: refuse a declared size other than the images' before decoding.
    if (header.width != 16 || header.height != 12) return 0;
    const cv::Mat mask = cv::imread(path.string(), cv::IMREAD_GRAYSCALE);
    if (!mask.empty() && (mask.cols != 16 || mask.rows != 12)) __builtin_trap();
  } catch (const sdoslam::Error&) {
  }
  return 0;
}
