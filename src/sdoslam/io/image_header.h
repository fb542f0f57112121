#pragma once

#include <filesystem>
#include <optional>

namespace sdoslam {

// Width, height, bit depth and colour type a PNG file declares in its IHDR chunk, read from its
// first 26 bytes without decoding it: readers refuse an image of the wrong size before decoding
// (a 16k x 16k PNG decodes to 853 MB). Hand-written because OpenCV 4.6 has no header-only query;
// the layout is fixed by the PNG specification (signature, then IHDR: length, type, width,
// height, bit depth, colour type; big-endian).
struct PngHeader {
  int width = 0, height = 0, bit_depth = 0, colour_type = 0;
};

// Throws Error naming the file when it cannot be opened, is not a regular file (a FIFO would
// block the read; core/regular_file.h) or is not a PNG.
PngHeader ReadPngHeader(const std::filesystem::path& path);
// nullopt when the file is missing or not a PNG (other formats are checked after decoding);
// throws Error naming it when it exists but is not a regular file.
std::optional<PngHeader> TryReadPngHeader(const std::filesystem::path& path);

}  // namespace sdoslam
