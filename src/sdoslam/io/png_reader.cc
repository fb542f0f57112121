#include "sdoslam/io/png_reader.h"

#include <libdeflate.h>

#include <array>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "sdoslam/core/regular_file.h"

namespace sdoslam {
namespace {

constexpr std::array<uint8_t, 8> kSignature = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
// cv::imread refuses more pixels than this (CV_IO_MAX_IMAGE_PIXELS); so do we, through OpenCV.
constexpr uint64_t kMaxPixels = uint64_t{1} << 30;

uint32_t BigEndian32(const uint8_t* p) {
  return (uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) | (uint32_t{p[2]} << 8) | uint32_t{p[3]};
}

// Undoes the Sub filter with the running sums held in registers, one per byte of a pixel: the
// plain loop (row[i] += row[i - bpp]) waits on a store and a load per byte, which made a 16-bit
// mask's unfiltering take ten times its inflating.
template <size_t kBpp>
void UnfilterSub(uint8_t* row, size_t length) {
  std::array<uint8_t, kBpp> left{};
  for (size_t i = 0; i + kBpp <= length; i += kBpp) {
    for (size_t c = 0; c < kBpp; ++c) {
      left[c] = static_cast<uint8_t>(left[c] + row[i + c]);
      row[i + c] = left[c];
    }
  }
}

// UnfilterSub by bytes per pixel (grey, grey 16, RGBA, RGB 16, RGBA 16); null: the plain loop.
constexpr std::array<void (*)(uint8_t*, size_t), 9> kSubByPixelSize = {
    nullptr, UnfilterSub<1>, UnfilterSub<2>, nullptr,       UnfilterSub<4>,
    nullptr, UnfilterSub<6>, nullptr,        UnfilterSub<8>};

// Undoes one row's filter in place (PNG specification, section 9). `previous` is the row above,
// already unfiltered (zeros for the first row); bpp is the bytes per pixel, at least 1.
bool Unfilter(uint8_t filter, uint8_t* row, const uint8_t* previous, size_t length, size_t bpp) {
  switch (filter) {
    case 0:  // None
      return true;
    case 1:  // Sub; length is a whole number of pixels
      if (bpp < kSubByPixelSize.size() && kSubByPixelSize[bpp] != nullptr) {
        kSubByPixelSize[bpp](row, length);
      } else {  // 8-bit RGB among them: GCC vectorises the template badly for 3 (5.0 -> 6.1 ms)
        for (size_t i = bpp; i < length; ++i) row[i] = static_cast<uint8_t>(row[i] + row[i - bpp]);
      }
      return true;
    case 2:  // Up
      for (size_t i = 0; i < length; ++i) row[i] = static_cast<uint8_t>(row[i] + previous[i]);
      return true;
    case 3:  // Average
      for (size_t i = 0; i < length; ++i) {
        const int left = i >= bpp ? row[i - bpp] : 0;
        row[i] = static_cast<uint8_t>(row[i] + ((left + previous[i]) >> 1));
      }
      return true;
    case 4:  // Paeth
      for (size_t i = 0; i < length; ++i) {
        const int a = i >= bpp ? row[i - bpp] : 0, b = previous[i],
                  c = i >= bpp ? previous[i - bpp] : 0;
        const int pa = std::abs(b - c), pb = std::abs(a - c), pc = std::abs(a + b - 2 * c);
        const int predictor = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
        row[i] = static_cast<uint8_t>(row[i] + predictor);
      }
      return true;
    default:
      return false;
  }
}

struct DecompressorDeleter {
  void operator()(libdeflate_decompressor* d) const { libdeflate_free_decompressor(d); }
};

// The header and the concatenated image data of a PNG of the kinds we decode; nullopt for
// anything else (OpenCV's decoder then reads it) and for a damaged file.
struct PngChunks {
  uint32_t width = 0, height = 0;
  int bit_depth = 0, colour_type = -1;
  std::vector<uint8_t> compressed;
};

std::optional<PngChunks> ReadChunks(std::span<const uint8_t> bytes) {
  if (bytes.size() < kSignature.size() ||
      std::memcmp(bytes.data(), kSignature.data(), kSignature.size()) != 0)
    return std::nullopt;
  PngChunks png;
  bool ended = false;
  for (size_t at = kSignature.size(); !ended;) {
    if (bytes.size() - at < 12) return std::nullopt;  // truncated
    const uint32_t length = BigEndian32(bytes.data() + at);
    if (length > 0x7fffffffu || bytes.size() - at - 12 < length) return std::nullopt;
    const uint8_t* type = bytes.data() + at + 4;
    const uint8_t* data = type + 4;
    if (libdeflate_crc32(0, type, length + 4) != BigEndian32(data + length)) return std::nullopt;
    const bool first = at == kSignature.size();
    if (std::memcmp(type, "IHDR", 4) == 0) {
      if (!first || length != 13) return std::nullopt;
      png.width = BigEndian32(data);
      png.height = BigEndian32(data + 4);
      png.bit_depth = data[8];
      png.colour_type = data[9];
      // Compression, filter method and interlacing: only method 0, and no Adam7.
      if (data[10] != 0 || data[11] != 0 || data[12] != 0) return std::nullopt;
    } else if (first) {
      return std::nullopt;
    } else if (std::memcmp(type, "IDAT", 4) == 0) {
      png.compressed.insert(png.compressed.end(), data, data + length);
    } else if (std::memcmp(type, "IEND", 4) == 0) {
      ended = true;
    } else if ((type[0] & 0x20) == 0 || std::memcmp(type, "tRNS", 4) == 0 ||
               std::memcmp(type, "eXIf", 4) == 0) {
      // A palette or another critical chunk, transparency that OpenCV turns into alpha, or an
      // orientation OpenCV may apply: OpenCV's own decoder knows what to do with them.
      return std::nullopt;
    }
    at += size_t{length} + 12;
  }
  return png;
}

// The unfiltered rows of `raw` (each behind its filter byte, `stride` bytes) as an OpenCV image:
// BGR(A), native 16-bit samples.
cv::Mat ToMat(std::vector<uint8_t>& raw, uint32_t width, uint32_t height, int bit_depth,
              int channels, size_t stride) {
  const int rows = static_cast<int>(height), cols = static_cast<int>(width);
  cv::Mat image;
  if (bit_depth == 8) {
    // The filter byte in front of each row is skipped by a step of stride + 1.
    const cv::Mat wrapped(rows, cols, CV_8UC(channels), raw.data() + 1, stride + 1);
    if (channels == 1) {
      wrapped.copyTo(image);
    } else {
      cv::cvtColor(wrapped, image, channels == 3 ? cv::COLOR_RGB2BGR : cv::COLOR_RGBA2BGRA);
    }
    return image;
  }
  // 16-bit samples are big-endian in the file; OpenCV's are native, and colour is BGR(A).
  image.create(rows, cols, CV_16UC(channels));
  for (int y = 0; y < rows; ++y) {
    const uint8_t* in = raw.data() + static_cast<size_t>(y) * (stride + 1) + 1;
    auto* out = image.ptr<uint16_t>(y);
    if (channels == 1) {  // depth images: the loop the compiler vectorises
      for (int x = 0; x < cols; ++x)
        out[x] = static_cast<uint16_t>((in[2 * x] << 8) | in[2 * x + 1]);
      continue;
    }
    for (int x = 0; x < cols; ++x) {
      for (int c = 0; c < channels; ++c) {
        const int from = channels >= 3 && c < 3 ? 2 - c : c;
        const uint8_t* sample = in + (static_cast<size_t>(x) * channels + from) * 2;
        out[x * channels + c] = static_cast<uint16_t>((sample[0] << 8) | sample[1]);
      }
    }
  }
  return image;
}

}  // namespace

std::optional<cv::Mat> DecodePng(std::span<const uint8_t> bytes) {
  std::optional<PngChunks> png = ReadChunks(bytes);
  if (!png) return std::nullopt;
  const uint32_t width = png->width, height = png->height;
  const int bit_depth = png->bit_depth, colour_type = png->colour_type;
  const std::vector<uint8_t>& compressed = png->compressed;
  const int channels = colour_type == 0 ? 1 : colour_type == 2 ? 3 : colour_type == 6 ? 4 : 0;
  if (channels == 0 || (bit_depth != 8 && bit_depth != 16) || width == 0 || height == 0 ||
      width > 0x7fffffffu || height > 0x7fffffffu ||
      uint64_t{width} * uint64_t{height} > kMaxPixels)
    return std::nullopt;

  const size_t bytes_per_sample = static_cast<size_t>(bit_depth / 8);
  const size_t bpp = bytes_per_sample * static_cast<size_t>(channels);
  const size_t stride = size_t{width} * bpp;
  const size_t raw_size = size_t{height} * (stride + 1);
  // DEFLATE expands at most about 1032:1; a header that promises more than its data can hold
  // would make us allocate gigabytes for a few bytes of file.
  if (raw_size / 1032 > compressed.size() + 64) return std::nullopt;
  std::vector<uint8_t> raw(raw_size);
  const std::unique_ptr<libdeflate_decompressor, DecompressorDeleter> decompressor(
      libdeflate_alloc_decompressor());
  if (!decompressor) return std::nullopt;
  size_t produced = 0;
  if (libdeflate_zlib_decompress(decompressor.get(), compressed.data(), compressed.size(),
                                 raw.data(), raw.size(), &produced) != LIBDEFLATE_SUCCESS ||
      produced != raw.size())
    return std::nullopt;

  const std::vector<uint8_t> zeros(stride, 0);
  for (size_t y = 0; y < height; ++y) {
    uint8_t* row = raw.data() + y * (stride + 1);
    const uint8_t* previous = y == 0 ? zeros.data() : row - stride;  // the row above, unfiltered
    if (!Unfilter(row[0], row + 1, previous, stride, bpp)) return std::nullopt;
  }

  return ToMat(raw, width, height, bit_depth, channels, stride);
}

cv::Mat ReadImage(const std::filesystem::path& path, int imread_flags) {
  // Checked at every read, not once at the start: an image replaced by a FIFO during a run
  // fails with its name instead of blocking the reader.
  const std::optional<std::string> file = ReadRegularFileIfExists(path);
  if (!file || file->empty()) return {};
  const std::span<const uint8_t> bytes(reinterpret_cast<const uint8_t*>(file->data()),
                                       file->size());
  if (std::optional<cv::Mat> image = DecodePng(bytes)) {
    const bool as_is = imread_flags == cv::IMREAD_UNCHANGED ||
                       (imread_flags == cv::IMREAD_COLOR && image->type() == CV_8UC3) ||
                       (imread_flags == cv::IMREAD_GRAYSCALE && image->type() == CV_8UC1);
    if (as_is) return *image;
  }
  return cv::imdecode(
      cv::Mat(1, static_cast<int>(bytes.size()), CV_8U, const_cast<uint8_t*>(bytes.data())),
      imread_flags);
}

}  // namespace sdoslam
