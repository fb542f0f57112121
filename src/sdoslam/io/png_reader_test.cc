#include "sdoslam/io/png_reader.h"

#include <gtest/gtest.h>
#include <libdeflate.h>
#include <sys/stat.h>

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <string>
#include <vector>

#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

void PutBigEndian32(std::vector<uint8_t>* out, uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) out->push_back(static_cast<uint8_t>(v >> shift));
}

void PutChunk(std::vector<uint8_t>* out, const char* type, const std::vector<uint8_t>& data) {
  PutBigEndian32(out, static_cast<uint32_t>(data.size()));
  std::vector<uint8_t> body(type, type + 4);
  body.insert(body.end(), data.begin(), data.end());
  out->insert(out->end(), body.begin(), body.end());
  PutBigEndian32(out, libdeflate_crc32(0, body.data(), body.size()));
}

// The predictor a PNG filter subtracts when encoding (specification, section 9).
int Predictor(int filter, int a, int b, int c) {
  switch (filter) {
    case 1:
      return a;
    case 2:
      return b;
    case 3:
      return (a + b) / 2;
    case 4: {
      const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
      return pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
    }
    default:
      return 0;
  }
}

// An encoder of our own for `image` (CV_8U or CV_16U, 1, 3 or 4 channels, BGR order as OpenCV
// holds it), so the test controls what OpenCV's writer never picks: every row filter in turn.
std::vector<uint8_t> EncodePng(const cv::Mat& image, int interlace = 0,
                               const char* extra_chunk = nullptr) {
  const int channels = image.channels();
  const int bytes_per_sample = image.depth() == CV_16U ? 2 : 1;
  const int bpp = channels * bytes_per_sample;
  std::vector<uint8_t> scanlines;
  std::vector<uint8_t> previous(static_cast<size_t>(image.cols * bpp), 0);
  for (int y = 0; y < image.rows; ++y) {
    std::vector<uint8_t> row;  // file order: RGB(A), big-endian samples
    for (int x = 0; x < image.cols; ++x) {
      for (int c = 0; c < channels; ++c) {
        const int from = channels >= 3 && c < 3 ? 2 - c : c;
        const int v = bytes_per_sample == 2 ? image.ptr<uint16_t>(y)[x * channels + from]
                                            : image.ptr<uint8_t>(y)[x * channels + from];
        if (bytes_per_sample == 2) row.push_back(static_cast<uint8_t>(v >> 8));
        row.push_back(static_cast<uint8_t>(v));
      }
    }
    const int filter = y % 5;
    scanlines.push_back(static_cast<uint8_t>(filter));
    for (size_t i = 0; i < row.size(); ++i) {
      const int a = i >= static_cast<size_t>(bpp) ? row[i - bpp] : 0;
      const int c = i >= static_cast<size_t>(bpp) ? previous[i - bpp] : 0;
      scanlines.push_back(static_cast<uint8_t>(row[i] - Predictor(filter, a, previous[i], c)));
    }
    previous = row;
  }
  libdeflate_compressor* compressor = libdeflate_alloc_compressor(6);
  std::vector<uint8_t> compressed(libdeflate_zlib_compress_bound(compressor, scanlines.size()));
  compressed.resize(libdeflate_zlib_compress(compressor, scanlines.data(), scanlines.size(),
                                             compressed.data(), compressed.size()));
  libdeflate_free_compressor(compressor);

  std::vector<uint8_t> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  std::vector<uint8_t> header;
  PutBigEndian32(&header, static_cast<uint32_t>(image.cols));
  PutBigEndian32(&header, static_cast<uint32_t>(image.rows));
  header.push_back(static_cast<uint8_t>(8 * bytes_per_sample));
  header.push_back(static_cast<uint8_t>(channels == 1 ? 0 : channels == 3 ? 2 : 6));
  header.insert(header.end(), {0, 0, static_cast<uint8_t>(interlace)});
  PutChunk(&png, "IHDR", header);
  if (extra_chunk != nullptr) PutChunk(&png, extra_chunk, {0, 0});
  // Two IDAT chunks: the stream may be split anywhere.
  const size_t half = compressed.size() / 2;
  PutChunk(&png, "IDAT", std::vector<uint8_t>(compressed.begin(), compressed.begin() + half));
  PutChunk(&png, "IDAT", std::vector<uint8_t>(compressed.begin() + half, compressed.end()));
  PutChunk(&png, "IEND", {});
  return png;
}

cv::Mat RandomImage(int type, uint32_t seed) {
  cv::Mat image(37, 29, type);
  cv::RNG rng(seed);
  rng.fill(image, cv::RNG::UNIFORM, 0, image.depth() == CV_16U ? 65536 : 256);
  // Smooth stretches too, where the predictors' ties (Paeth's order) decide the result.
  image.rowRange(10, 20).setTo(cv::Scalar::all(7));
  return image;
}

void ExpectSame(const cv::Mat& a, const cv::Mat& b) {
  ASSERT_EQ(a.type(), b.type());
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0);
}

TEST(DecodePng, EveryFilterDepthAndLayoutAgreesWithOpenCv) {
  for (int type : {CV_8UC1, CV_8UC3, CV_8UC4, CV_16UC1, CV_16UC3, CV_16UC4}) {
    SCOPED_TRACE(type);
    const cv::Mat image = RandomImage(type, static_cast<uint32_t>(type) + 1);
    const std::vector<uint8_t> png = EncodePng(image);
    const std::optional<cv::Mat> ours = DecodePng(png);
    ASSERT_TRUE(ours.has_value());
    ExpectSame(*ours, image);
    ExpectSame(*ours, cv::imdecode(png, cv::IMREAD_UNCHANGED));  // the encoder is right too
  }
}

TEST(DecodePng, LeavesOtherLayoutsAndDamagedFilesToOpenCv) {
  const cv::Mat image = RandomImage(CV_8UC3, 3);
  EXPECT_FALSE(DecodePng(EncodePng(image, /*interlace=*/1)).has_value());
  EXPECT_FALSE(DecodePng(EncodePng(image, 0, "tRNS")).has_value());
  EXPECT_FALSE(DecodePng(EncodePng(image, 0, "PLTE")).has_value());
  EXPECT_TRUE(DecodePng(EncodePng(image, 0, "tEXt")).has_value());  // ancillary: ignored

  std::vector<uint8_t> png = EncodePng(image);
  std::vector<uint8_t> damaged = png;
  damaged[png.size() / 2] ^= 0x10;  // inside IDAT: the chunk's CRC no longer matches
  EXPECT_FALSE(DecodePng(damaged).has_value());
  EXPECT_FALSE(DecodePng(std::span(png).first(png.size() - 20)).has_value());  // truncated
  EXPECT_FALSE(DecodePng(std::span(png).first(5)).has_value());
  const std::vector<uint8_t> not_png(100, 'x');
  EXPECT_FALSE(DecodePng(not_png).has_value());
}

TEST(ReadImage, GivesWhatImreadGivesForEveryFlag) {
  testing::TempDir dir;
  const cv::Mat colour = RandomImage(CV_8UC3, 5);
  const cv::Mat grey = RandomImage(CV_8UC1, 6);
  const cv::Mat depth = RandomImage(CV_16UC1, 7);
  ASSERT_TRUE(cv::imwrite((dir / "colour.png").string(), colour));
  ASSERT_TRUE(cv::imwrite((dir / "grey.png").string(), grey));
  ASSERT_TRUE(cv::imwrite((dir / "depth.png").string(), depth));
  ASSERT_TRUE(cv::imwrite((dir / "colour.jpg").string(), colour));
  for (const char* name : {"colour.png", "grey.png", "depth.png", "colour.jpg"}) {
    for (int flags : {cv::IMREAD_UNCHANGED, cv::IMREAD_COLOR, cv::IMREAD_GRAYSCALE}) {
      SCOPED_TRACE(std::string(name) + " flags " + std::to_string(flags));
      ExpectSame(ReadImage(dir / name, flags), cv::imread((dir / name).string(), flags));
    }
  }
  EXPECT_TRUE(ReadImage(dir / "missing.png", cv::IMREAD_COLOR).empty());
  testing::WriteText(dir / "broken.png", "not an image");
  EXPECT_TRUE(ReadImage(dir / "broken.png", cv::IMREAD_COLOR).empty());
}

// An image that is a FIFO blocked the reader until something wrote to it (a run hung); a folder
// or a device is no image either. Each is named at once, at every read.
TEST(ReadImage, AnImageThatIsNoRegularFileIsNamed) {
  testing::TempDir dir;
  ASSERT_EQ(mkfifo((dir / "fifo.png").c_str(), 0600), 0);
  for (const std::filesystem::path& path :
       {dir / "fifo.png", dir.path(), std::filesystem::path("/dev/zero")}) {
    EXPECT_EQ(testing::MessageOf([&] { ReadImage(path, cv::IMREAD_COLOR); }),
              path.string() + ": not a regular file");
  }
}

}  // namespace
}  // namespace sdoslam
