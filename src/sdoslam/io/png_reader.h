#pragma once

#include <cstdint>
#include <filesystem>
#include <opencv2/core.hpp>
#include <optional>
#include <span>

namespace sdoslam {

// Decodes the PNG layouts RGB-D datasets store (non-interlaced 8- or 16-bit grey, RGB or RGBA,
// no palette, no transparency chunk, no EXIF) to what cv::imread(..., IMREAD_UNCHANGED) gives:
// CV_8U / CV_16U with 1, 3 (BGR) or 4 (BGRA) channels, samples in native byte order.
// nullopt for any other layout, a damaged chunk (CRC) or a damaged zlib stream: the caller then
// hands the bytes to OpenCV, which decides as before.
//
// Hand-written because of speed: libpng inflates with zlib, and that was a sixth of a threaded
// sdo run's CPU. libdeflate (a Debian package) inflates the same streams faster (a depth image
// in half the time; docs/performance.md, Decoding), but it only inflates; the PNG framing
// around it (chunks, CRCs, the five row filters) is this file.
std::optional<cv::Mat> DecodePng(std::span<const uint8_t> bytes);

// cv::imread(path, flags) for IMREAD_UNCHANGED, IMREAD_COLOR and IMREAD_GRAYSCALE, decoding the
// layouts above with DecodePng and everything else with OpenCV. Empty when the file does not
// exist or cannot be decoded, as cv::imread; throws Error naming it when it exists but is not a
// regular file, is larger than kMaxInputFileBytes or cannot be read (core/regular_file.h).
cv::Mat ReadImage(const std::filesystem::path& path, int imread_flags);

}  // namespace sdoslam
