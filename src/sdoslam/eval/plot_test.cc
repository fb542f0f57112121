#include "sdoslam/eval/plot.h"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

TEST(NiceTicks, UsesOneTwoFiveSteps) {
  EXPECT_EQ(NiceTicks(0.0, 1.0, 5),
            (std::vector<double>{0.0, 0.2, 0.4, 0.6000000000000001, 0.8, 1.0}));
  const auto t = NiceTicks(-3.3, 7.9, 6);
  ASSERT_GE(t.size(), 2u);
  EXPECT_DOUBLE_EQ(t[1] - t[0], 2.0);
  EXPECT_GE(t.front(), -3.3);
  EXPECT_LE(t.back(), 7.9);
}

TEST(Plot, PngHasTheSeriesColourWhereTheDataIs) {
  testing::TempDir dir;
  Plot plot{"title", "x", "y", false, {}};
  plot.series.push_back({"", {{0, 0}, {1, 1}}, 0xff0000, 3.0, false});  // pure red diagonal
  SavePlot(plot, dir / "p.png", 400, 300);
  const cv::Mat image = cv::imread((dir / "p.png").string());
  ASSERT_EQ(image.size(), cv::Size(400, 300));
  // The diagonal runs from the bottom-left to the top-right of the frame: its middle is red.
  // Frame: left 100, right 370, top 50, bottom 230 (see plot.cc); data padded by 5 %.
  const cv::Vec3b mid = image.at<cv::Vec3b>(140, 235);
  EXPECT_GT(mid[2], 200);
  EXPECT_LT(mid[0], 80);
  // Far from the diagonal (the frame's top-left and bottom-right) nothing is red.
  auto red_pixels = [&](cv::Rect box) {
    int n = 0;
    for (int y = box.y; y < box.y + box.height; ++y)
      for (int x = box.x; x < box.x + box.width; ++x) {
        const cv::Vec3b p = image.at<cv::Vec3b>(y, x);
        n += p[2] > 200 && p[1] < 100 && p[0] < 100;
      }
    return n;
  };
  EXPECT_EQ(red_pixels({105, 55, 80, 50}), 0);
  EXPECT_EQ(red_pixels({280, 180, 80, 45}), 0);
  EXPECT_GT(red_pixels({220, 125, 30, 30}), 10);
}

TEST(Plot, SvgAndBadExtension) {
  testing::TempDir dir;
  Plot plot{"a <b>", "x", "y", true, {{"s", {{0, 0}, {2, 1}}, 0x00ff00, 1.5, false}}};
  SavePlot(plot, dir / "p.svg");
  const std::string svg = testing::ReadText(dir / "p.svg");
  EXPECT_NE(svg.find("<polyline fill=\"none\" stroke=\"#00ff00\""), std::string::npos);
  EXPECT_NE(svg.find("a &lt;b&gt;"), std::string::npos);
  EXPECT_EQ(svg.substr(svg.size() - 7), "</svg>\n");
  EXPECT_THROW(SavePlot(plot, dir / "p.jpg"), Error);
}

}  // namespace
}  // namespace sdoslam
