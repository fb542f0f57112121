#include "sdoslam/io/image_header.h"

#include <array>
#include <cstdint>
#include <cstring>
#include <string>

#include "sdoslam/core/error.h"
#include "sdoslam/core/regular_file.h"

namespace sdoslam {

std::optional<PngHeader> TryReadPngHeader(const std::filesystem::path& path) {
  static constexpr std::array<unsigned char, 8> kSignature = {0x89, 'P',  'N',  'G',
                                                              '\r', '\n', 0x1a, '\n'};
  std::array<unsigned char, 26> head{};
  const std::optional<std::string> bytes = ReadRegularFileHead(path, head.size());
  if (!bytes || bytes->size() < head.size()) return std::nullopt;
  std::memcpy(head.data(), bytes->data(), head.size());
  if (std::memcmp(head.data(), kSignature.data(), kSignature.size()) != 0) return std::nullopt;
  if (std::memcmp(head.data() + 12, "IHDR", 4) != 0) return std::nullopt;
  auto big_endian = [&](int offset) {
    return (uint32_t{head[offset]} << 24) | (uint32_t{head[offset + 1]} << 16) |
           (uint32_t{head[offset + 2]} << 8) | uint32_t{head[offset + 3]};
  };
  const uint32_t width = big_endian(16), height = big_endian(20);
  // The specification caps both at 2^31 - 1; a larger value is a damaged file, for the decoder.
  if (width > 0x7fffffffu || height > 0x7fffffffu) return std::nullopt;
  return PngHeader{static_cast<int>(width), static_cast<int>(height), head[24], head[25]};
}

PngHeader ReadPngHeader(const std::filesystem::path& path) {
  if (!ReadRegularFileHead(path, 0)) throw Error(path.string() + ": cannot open");
  const std::optional<PngHeader> header = TryReadPngHeader(path);
  if (!header) throw Error(path.string() + ": not a PNG file");
  return *header;
}

}  // namespace sdoslam
