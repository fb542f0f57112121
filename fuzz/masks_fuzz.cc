// Mask images as eval-masks, the oracle mode and the file segmenter read them: the PNG header
// check, then decoding as an 8-bit label image. Every input also goes through our own PNG
// decoder (io/png_reader.h), whatever its size and layout: what it returns must be the size
// its header declares, in one of the layouts it promises.
#include <opencv2/imgcodecs.hpp>
#include <span>

#include "fuzz_util.h"
#include "sdoslam/core/error.h"
#include "sdoslam/io/image_header.h"
#include "sdoslam/io/png_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = sdoslam::fuzz::WriteInput("mask.png", sdoslam::fuzz::AsText(data, size));
  if (const std::optional<cv::Mat> decoded = sdoslam::DecodePng(std::span(data, size))) {
    const std::optional<sdoslam::PngHeader> header = sdoslam::TryReadPngHeader(path);
    const int type = decoded->type();
    const bool layout = type == CV_8UC1 || type == CV_8UC3 || type == CV_8UC4 || type == CV_16UC1 ||
                        type == CV_16UC3 || type == CV_16UC4;
    if (!header || !layout || decoded->cols != header->width || decoded->rows != header->height)
      __builtin_trap();
  }
  try {
    const sdoslam::PngHeader header = sdoslam::ReadPngHeader(path);
    // As the readers do: refuse a declared size other than the images' before decoding.
    if (header.width != 16 || header.height != 12) return 0;
    const cv::Mat mask = sdoslam::ReadImage(path, cv::IMREAD_GRAYSCALE);
    if (!mask.empty() && (mask.cols != 16 || mask.rows != 12 || mask.type() != CV_8UC1))
      __builtin_trap();
  } catch (const sdoslam::Error&) {
  }
  return 0;
}
