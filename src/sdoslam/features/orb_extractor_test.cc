#include "sdoslam/features/orb_extractor.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <set>

namespace sdoslam {
namespace {

// A 640x480 image of random grey rectangles: corners everywhere, nothing repeating.
cv::Mat BlockImage(unsigned seed) {
  cv::Mat image(480, 640, CV_8UC1, cv::Scalar(128));
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> x(0, 639), y(0, 479), size(6, 40), grey(0, 255);
  for (int k = 0; k < 3000; ++k) {
    cv::rectangle(image, cv::Rect(x(rng), y(rng), size(rng), size(rng)), cv::Scalar(grey(rng)),
                  cv::FILLED);
  }
  cv::GaussianBlur(image, image, cv::Size(3, 3), 0.8);
  return image;
}

TEST(OrbExtractor, FindsAboutTheRequestedNumberSpreadOverTheImage) {
  const OrbExtractor orb(OrbOptions{});
  std::vector<cv::KeyPoint> kps;
  cv::Mat desc;
  orb.Extract(BlockImage(1), &kps, &desc);
  EXPECT_GT(kps.size(), 900u);
  EXPECT_LE(kps.size(), 1000u);
  EXPECT_EQ(desc.rows, static_cast<int>(kps.size()));
  EXPECT_EQ(desc.cols, 32);
  // Every cell of a 4x4 grid holds a fair share (an even spread gives 1/16 = 6 % each); a
  // strongest-first selection would pile up where the contrast is highest.
  int cells[16] = {};
  std::set<int> levels;
  for (const auto& k : kps) {
    cells[std::min(3, static_cast<int>(k.pt.y / 120)) * 4 +
          std::min(3, static_cast<int>(k.pt.x / 160))]++;
    levels.insert(k.octave);
  }
  for (int c : cells) EXPECT_GT(c, static_cast<int>(kps.size()) / 40) << "cell count " << c;
  EXPECT_EQ(levels.size(), 8u);
}

// With a budget area, the whole budget goes there, and the extra area keeps exactly the
// keypoints a whole-image budget put on it.
TEST(OrbExtractor, TheBudgetGoesToItsAreaAndTheExtraAreaKeepsWhatItHad) {
  const OrbExtractor orb(OrbOptions{});
  const cv::Mat image = BlockImage(3);
  std::vector<cv::KeyPoint> whole;
  cv::Mat whole_descriptors;
  orb.Extract(image, &whole, &whole_descriptors);
  // A mover over the right 60 % of the image; the budget keeps 8 px away from it.
  ExtractionAreas areas;
  areas.extra = cv::Mat(image.size(), CV_8U, cv::Scalar(0));
  areas.extra(cv::Rect(256, 0, 384, 480)).setTo(255);
  areas.budget = cv::Mat(image.size(), CV_8U, cv::Scalar(0));
  areas.budget(cv::Rect(0, 0, 248, 480)).setTo(255);
  std::vector<cv::KeyPoint> kps;
  cv::Mat desc;
  orb.Extract(image, &kps, &desc, areas);
  ASSERT_EQ(desc.rows, static_cast<int>(kps.size()));
  // Level-0 positions are level positions times the scale, rounded as Extract rounds them: a
  // keypoint may lie a pixel past the area's edge.
  int in_budget = 0, in_extra = 0, elsewhere = 0;
  for (const auto& k : kps) {
    if (k.pt.x < 249) {
      ++in_budget;
    } else if (k.pt.x >= 255) {
      ++in_extra;
    } else {
      ++elsewhere;
    }
  }
  int whole_in_extra = 0, whole_left = 0;
  for (const auto& k : whole) {
    whole_in_extra += k.pt.x >= 255.5;
    whole_left += k.pt.x < 248;
  }
  // One budget over the image leaves the left 40 % about 40 % of it; the budget area gets it all.
  EXPECT_LT(whole_left, 500);
  EXPECT_GT(in_budget, 900);
  EXPECT_LE(in_budget, 1000);
  EXPECT_EQ(elsewhere, 0);
  EXPECT_NEAR(in_extra, whole_in_extra, 2);
  // The extra keypoints are the whole-image extraction's, descriptors included.
  int same = 0;
  for (int i = 0; i < static_cast<int>(kps.size()); ++i) {
    if (kps[i].pt.x < 255) continue;
    for (int j = 0; j < static_cast<int>(whole.size()); ++j) {
      if (whole[j].octave == kps[i].octave && cv::norm(whole[j].pt - kps[i].pt) < 1e-3 &&
          cv::norm(whole_descriptors.row(j), desc.row(i), cv::NORM_HAMMING) == 0) {
        ++same;
        break;
      }
    }
  }
  EXPECT_EQ(same, in_extra);
}

TEST(OrbExtractor, LowContrastRegionsStillGetCornersFromTheLowerThreshold) {
  cv::Mat image = BlockImage(2);
  cv::Mat left = image(cv::Rect(0, 0, 320, 480));
  left.convertTo(left, -1, 0.08, 118);  // contrast of a few grey levels: FAST 20 finds nothing
  const OrbExtractor orb(OrbOptions{});
  std::vector<cv::KeyPoint> kps;
  cv::Mat desc;
  orb.Extract(image, &kps, &desc);
  int left_count = 0;
  for (const auto& k : kps) left_count += k.pt.x < 300;
  EXPECT_GT(left_count, 150);
}

TEST(DistributeEvenly, KeepsTheStrongestPerCellAndTheCount) {
  std::vector<cv::KeyPoint> kps;
  for (int k = 0; k < 100; ++k)
    kps.emplace_back(cv::Point2f(5.0f + k * 0.01f, 5.0f), 1.f, -1, 100.0f + k);  // a cluster
  kps.emplace_back(cv::Point2f(90, 90), 1.f, -1, 1.0f);                          // weak but alone
  kps.emplace_back(cv::Point2f(90, 10), 1.f, -1, 2.0f);
  const auto selected = DistributeEvenly(kps, cv::Rect(0, 0, 100, 100), 3);
  ASSERT_EQ(selected.size(), 3u);
  EXPECT_FLOAT_EQ(selected[0].response, 199.0f);  // the cluster's best
  std::set<float> xs;
  for (const auto& k : selected) xs.insert(k.pt.x);
  EXPECT_TRUE(xs.count(90.0f));
}

TEST(OrbExtractor, DescriptorsMatchUnderShiftAndOrientationFollowsRotation) {
  const cv::Mat image = BlockImage(3);
  cv::Mat rotated;
  cv::rotate(image, rotated, cv::ROTATE_90_CLOCKWISE);  // 480x640
  const OrbExtractor orb(OrbOptions{});
  std::vector<cv::KeyPoint> a, b;
  cv::Mat da, db;
  orb.Extract(image, &a, &da);
  orb.Extract(rotated, &b, &db);
  // Pixel (x, y) goes to (479 - y, x) under the rotation; angles grow by 90 degrees.
  int matched = 0, close = 0, angle_ok = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    if (a[i].octave != 0) continue;
    const cv::Point2f expected(479.0f - a[i].pt.y, a[i].pt.x);
    for (size_t j = 0; j < b.size(); ++j) {
      if (b[j].octave != 0 || cv::norm(b[j].pt - expected) > 0.5) continue;
      ++matched;
      close += DescriptorDistance(da.ptr<uint8_t>(static_cast<int>(i)),
                                  db.ptr<uint8_t>(static_cast<int>(j))) < 50;
      const double d = std::fmod(b[j].angle - a[i].angle + 720.0, 360.0);
      angle_ok += std::abs(d - 90.0) < 5.0;
    }
  }
  ASSERT_GT(matched, 100);
  EXPECT_GT(angle_ok, 0.9 * matched);
  EXPECT_GT(close, 0.8 * matched);  // rotation-invariant descriptors
}

// A feature of pyramid level L is described on the image at 1.2^(2L), bit for bit as cv::ORB
// describes a keypoint of octave L on the level image (it samples its own L-th pyramid image of
// what it is handed): the descriptors sdoslam was tuned with. Sampling the level image itself
// (the patch 1.2^L times smaller) differs in a median 35, 70 and 100 of the 256 bits at levels
// 1, 2 and 3.
TEST(OrbExtractor, ALevelIsDescribedAtItsScaleSquared) {
  const cv::Mat image = BlockImage(5);
  const OrbExtractor orb(OrbOptions{});
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  orb.Extract(image, &keypoints, &descriptors);
  const cv::Ptr<cv::ORB> reference =
      cv::ORB::create(1 << 20, 1.2f, 1, /*edgeThreshold=*/19, 0, 2, cv::ORB::HARRIS_SCORE, 31);
  for (int level = 0; level <= 7; ++level) {
    const double scale = std::pow(1.2, level);
    cv::Mat level_image;
    cv::resize(image, level_image,
               cv::Size(static_cast<int>(std::lround(640 / scale)),
                        static_cast<int>(std::lround(480 / scale))),
               0, 0, cv::INTER_LINEAR);
    std::vector<cv::KeyPoint> on_level;
    std::vector<int> rows;
    for (size_t i = 0; i < keypoints.size(); ++i) {
      if (keypoints[i].octave != level) continue;
      cv::KeyPoint k = keypoints[i];
      k.pt /= static_cast<float>(scale);
      on_level.push_back(k);
      rows.push_back(static_cast<int>(i));
    }
    ASSERT_GT(on_level.size(), level <= 3 ? 50u : 5u);
    cv::Mat expected;
    reference->compute(level_image, on_level, expected);
    ASSERT_EQ(on_level.size(), rows.size());
    int equal = 0;
    for (size_t k = 0; k < rows.size(); ++k) {
      equal += DescriptorDistance(descriptors.ptr<uint8_t>(rows[k]),
                                  expected.ptr<uint8_t>(static_cast<int>(k))) == 0;
    }
    // All but the odd keypoint that lands on another pixel: the test takes the level position
    // back from the full-resolution one, in float.
    EXPECT_GE(equal, 0.95 * static_cast<double>(rows.size())) << "level " << level;
  }
}

// A view with nothing to track is an empty result, not an error: the tracker calls the frame
// lost and goes on.
TEST(OrbExtractor, ImagesWithoutCornersGiveNoFeatures) {
  const OrbExtractor orb(OrbOptions{});
  for (int value : {0, 128, 255}) {  // black, uniform, saturated
    const cv::Mat image(480, 640, CV_8UC1, cv::Scalar(value));
    std::vector<cv::KeyPoint> kps;
    cv::Mat desc;
    orb.Extract(image, &kps, &desc);
    EXPECT_TRUE(kps.empty()) << value;
    EXPECT_EQ(desc.rows, 0) << value;
    EXPECT_EQ(desc.cols, 32) << value;
    EXPECT_EQ(desc.type(), CV_8U) << value;
  }
}

// Texture in one corner of a plain wall: the fine levels of the pyramid find corners there; on
// the coarse ones the corner falls inside the border that descriptors need, and they find none. A
// level without keypoints gives an empty descriptor matrix, which once ended the whole run
// (OpenCV's vconcat refuses it).
TEST(OrbExtractor, PyramidLevelsWithoutCornersAreLeftOut) {
  cv::Mat image(480, 640, CV_8UC1, cv::Scalar(128));
  cv::Mat patch = image(cv::Rect(20, 20, 40, 40));
  cv::RNG rng(7);
  rng.fill(patch, cv::RNG::UNIFORM, 0, 256);
  const OrbExtractor orb(OrbOptions{});
  std::vector<cv::KeyPoint> kps;
  cv::Mat desc;
  orb.Extract(image, &kps, &desc);
  std::set<int> levels;
  for (const auto& k : kps) levels.insert(k.octave);
  ASSERT_FALSE(kps.empty());
  EXPECT_TRUE(levels.count(0));
  EXPECT_LT(levels.size(), 8u) << "every level found corners: the test image is too rich";
  EXPECT_EQ(desc.rows, static_cast<int>(kps.size()));
  EXPECT_EQ(desc.cols, 32);
}

TEST(DescriptorDistance, CountsDifferingBits) {
  cv::RNG rng(3);
  for (int trial = 0; trial < 200; ++trial) {
    uint8_t a[32], b[32];
    for (int k = 0; k < 32; ++k) {
      a[k] = static_cast<uint8_t>(rng.uniform(0, 256));
      b[k] = static_cast<uint8_t>(rng.uniform(0, 256));
    }
    int expected = 0;
    for (int k = 0; k < 32; ++k) {
      for (int bit = 0; bit < 8; ++bit) expected += ((a[k] ^ b[k]) >> bit) & 1;
    }
    // Unaligned rows too: descriptors of a cv::Mat row need not be 8-byte aligned.
    uint8_t shifted[33];
    std::memcpy(shifted + 1, b, 32);
    EXPECT_EQ(DescriptorDistance(a, b), expected);
    EXPECT_EQ(DescriptorDistance(a, shifted + 1), expected);
  }
  uint8_t zeros[32] = {}, ones[32];
  std::memset(ones, 0xFF, 32);
  EXPECT_EQ(DescriptorDistance(zeros, ones), 256);
  EXPECT_EQ(DescriptorDistance(ones, ones), 0);
}

}  // namespace
}  // namespace sdoslam
