#include "sdoslam/io/image_header.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <opencv2/imgcodecs.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

TEST(PngHeader, ReadsSizeAndDepthAndRejectsOtherFiles) {
  testing::TempDir dir;
  ASSERT_TRUE(cv::imwrite((dir / "x.png").string(), cv::Mat(7, 11, CV_16U, cv::Scalar(0))));
  const PngHeader h = ReadPngHeader(dir / "x.png");
  EXPECT_EQ(h.width, 11);
  EXPECT_EQ(h.height, 7);
  EXPECT_EQ(h.bit_depth, 16);
  EXPECT_EQ(h.colour_type, 0);  // grey
  ASSERT_TRUE(cv::imwrite((dir / "c.png").string(), cv::Mat(3, 5, CV_8UC3, cv::Scalar(0))));
  EXPECT_EQ(ReadPngHeader(dir / "c.png").colour_type, 2);  // truecolour
  testing::WriteText(dir / "y.png", "not a png at all, but long enough");
  EXPECT_THROW(ReadPngHeader(dir / "y.png"), Error);
  EXPECT_FALSE(TryReadPngHeader(dir / "y.png").has_value());
  ASSERT_TRUE(cv::imwrite((dir / "z.jpg").string(), cv::Mat(3, 5, CV_8UC3, cv::Scalar(0))));
  EXPECT_FALSE(TryReadPngHeader(dir / "z.jpg").has_value());
  EXPECT_FALSE(TryReadPngHeader(dir / "missing.png").has_value());
  EXPECT_THROW(ReadPngHeader(dir / "missing.png"), Error);
}

// The header was read before the image (to refuse a wrong size undecoded): a FIFO blocked it.
TEST(PngHeader, AFileThatIsNoRegularFileIsNamed) {
  testing::TempDir dir;
  ASSERT_EQ(mkfifo((dir / "fifo.png").c_str(), 0600), 0);
  const std::string expected = (dir / "fifo.png").string() + ": not a regular file";
  EXPECT_EQ(testing::MessageOf([&] { TryReadPngHeader(dir / "fifo.png"); }), expected);
  EXPECT_EQ(testing::MessageOf([&] { ReadPngHeader(dir / "fifo.png"); }), expected);
}

}  // namespace
}  // namespace sdoslam
