#include "sdoslam/dynamic/lab.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>

namespace sdoslam {
namespace {

// OpenCV's conversion of the same image as floats in [0, 1] (the segmenters' former call). It
// interpolates its own tables, and is off the CIE formulas by up to about 0.4.
cv::Mat OpenCvLab(const cv::Mat& bgr) {
  cv::Mat f, lab;
  bgr.convertTo(f, CV_32F, 1.0 / 255.0);
  cv::cvtColor(f, lab, cv::COLOR_BGR2Lab);
  return lab;
}

// The CIE formulas in double precision, pixel by pixel, with no tables.
cv::Vec3d ExactLab(const cv::Vec3b& bgr) {
  auto linear = [](int v) {
    const double x = v / 255.0;
    return x <= 0.04045 ? x / 12.92 : std::pow((x + 0.055) / 1.055, 2.4);
  };
  const double r = linear(bgr[2]), g = linear(bgr[1]), b = linear(bgr[0]);
  const double x = (0.412453 * r + 0.357580 * g + 0.180423 * b) / 0.950456;
  const double y = 0.212671 * r + 0.715160 * g + 0.072169 * b;
  const double z = (0.019334 * r + 0.119193 * g + 0.950227 * b) / 1.088754;
  auto f = [](double t) { return t > 0.008856 ? std::cbrt(t) : 7.787 * t + 16.0 / 116.0; };
  return {116 * f(y) - 16, 500 * (f(x) - f(y)), 200 * (f(y) - f(z))};
}

double WorstDifference(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat difference;
  cv::absdiff(a, b, difference);
  double worst = 0;
  cv::minMaxLoc(difference.reshape(1), nullptr, &worst);
  return worst;
}

TEST(BgrToLab, FollowsTheCieFormulasAndOpenCvsConventions) {
  cv::Mat bgr(64, 256, CV_8UC3);
  // Row 0: every grey level (a = b = 0, L from 0 to 100, across the cube root's linear part).
  for (int x = 0; x < 256; ++x) bgr.at<cv::Vec3b>(0, x) = cv::Vec3b(x, x, x);
  // Row 1: the primaries and secondaries at full and low intensity.
  const cv::Vec3b corners[] = {{255, 0, 0},   {0, 255, 0},   {0, 0, 255}, {255, 255, 0},
                               {0, 255, 255}, {255, 0, 255}, {3, 0, 0},   {0, 0, 3}};
  for (int x = 0; x < 256; ++x) bgr.at<cv::Vec3b>(1, x) = corners[x % 8];
  cv::RNG rng(17);
  rng.fill(bgr.rowRange(2, bgr.rows), cv::RNG::UNIFORM, 0, 256);
  cv::Mat ours;
  BgrToLab(bgr, &ours);
  ASSERT_EQ(ours.type(), CV_32FC3);
  ASSERT_EQ(ours.size(), bgr.size());
  cv::Mat exact(bgr.size(), CV_32FC3);
  for (int y = 0; y < bgr.rows; ++y) {
    for (int x = 0; x < bgr.cols; ++x)
      exact.at<cv::Vec3f>(y, x) = ExactLab(bgr.at<cv::Vec3b>(y, x));
  }
  EXPECT_LT(WorstDifference(ours, exact), 0.01);
  // The channel order, white point and scales are OpenCV's (a swapped red and blue, or L in
  // [0, 255], would be off by tens).
  EXPECT_LT(WorstDifference(ours, OpenCvLab(bgr)), 0.5);
  // Published values: white, black, pure red (sRGB, D65).
  const cv::Vec3f white = ours.at<cv::Vec3f>(0, 255), black = ours.at<cv::Vec3f>(0, 0);
  EXPECT_NEAR(white[0], 100.0f, 0.01f);
  EXPECT_NEAR(white[1], 0.0f, 0.01f);
  EXPECT_NEAR(black[0], 0.0f, 0.01f);
  const cv::Vec3f red = ours.at<cv::Vec3f>(1, 2);
  EXPECT_NEAR(red[0], 53.24f, 0.05f);
  EXPECT_NEAR(red[1], 80.09f, 0.1f);
  EXPECT_NEAR(red[2], 67.20f, 0.1f);
}

TEST(BgrPixelToLab, FollowsTheCieFormulasForEveryPixelOfARandomImage) {
  cv::Mat bgr(32, 64, CV_8UC3);
  cv::RNG rng(5);
  rng.fill(bgr, cv::RNG::UNIFORM, 0, 256);
  cv::Mat image;
  BgrToLab(bgr, &image);
  for (int y = 0; y < bgr.rows; ++y) {
    for (int x = 0; x < bgr.cols; ++x) {
      const cv::Vec3b& p = bgr.at<cv::Vec3b>(y, x);
      const cv::Vec3f lab = BgrPixelToLab(p);
      // The segmenter's colours are the same whichever way they are converted.
      ASSERT_EQ(lab, image.at<cv::Vec3f>(y, x)) << "pixel " << x << ", " << y;
      const cv::Vec3d exact = ExactLab(p);
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(lab[c], exact[c], 0.01);
    }
  }
}

TEST(BgrToLab, RejectsImagesThatAreNotEightBitColour) {
  cv::Mat lab;
  EXPECT_THROW(BgrToLab(cv::Mat(4, 4, CV_32FC3, cv::Scalar(0.5, 0.5, 0.5)), &lab), cv::Exception);
  EXPECT_THROW(BgrToLab(cv::Mat(4, 4, CV_8UC1, cv::Scalar(1)), &lab), cv::Exception);
}

}  // namespace
}  // namespace sdoslam
