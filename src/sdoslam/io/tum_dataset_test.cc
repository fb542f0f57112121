#include "sdoslam/io/tum_dataset.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <opencv2/imgcodecs.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

CameraOptions SmallCamera() {
  CameraOptions o;
  o.width = 32;
  o.height = 24;
  o.fx = o.fy = 30;
  o.cx = 16;
  o.cy = 12;
  o.depth_max = 5.0;
  return o;
}

// Writes a tiny TUM-layout sequence: rgb at t = 1.00, 1.10, ...; depth 4 ms later, plus one
// unmatched depth frame. Depth values encode the frame number so association is checkable.
void WriteSequence(const std::filesystem::path& dir, int frames) {
  std::string rgb_list = "# color images\n# timestamp filename\n";
  std::string depth_list = "# depth maps\n";
  for (int k = 0; k < frames; ++k) {
    char name[64];
    const double t = 1.0 + 0.1 * k;
    std::snprintf(name, sizeof(name), "%.6f.png", t);
    cv::imwrite((dir / "rgb" / name).string(),
                cv::Mat(24, 32, CV_8UC3, cv::Scalar(k, 2 * k, 3 * k)));
    rgb_list += std::to_string(t) + " rgb/" + name + "\n";
    std::snprintf(name, sizeof(name), "%.6f.png", t + 0.004);
    cv::Mat depth(24, 32, CV_16UC1, cv::Scalar(5000 + 1000 * k));  // 1.0 m + 0.2 m per frame
    depth.at<uint16_t>(0, 0) = 0;                                  // missing
    depth.at<uint16_t>(0, 1) = 60000;                              // 12 m: beyond depth_max
    cv::imwrite((dir / "depth" / name).string(), depth);
    depth_list += std::to_string(t + 0.004) + " depth/" + name + "\n";
  }
  cv::imwrite((dir / "depth" / "9.png").string(), cv::Mat(24, 32, CV_16UC1, cv::Scalar(1)));
  depth_list += "9.0 depth/9.png\n";
  testing::WriteText(dir / "rgb.txt", rgb_list);
  testing::WriteText(dir / "depth.txt", depth_list);
}

class TumDatasetTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::filesystem::create_directories(dir_ / "rgb");
    std::filesystem::create_directories(dir_ / "depth");
    WriteSequence(dir_.path(), 4);
  }
  std::string ErrorOf(const TumDatasetOptions& options = {}, CameraOptions camera = SmallCamera(),
                      int load = -1) {
    try {
      TumDataset dataset(dir_.path(), camera, options);
      if (load >= 0) dataset.Load(load);
    } catch (const Error& e) {
      return e.what();
    }
    return "(no error)";
  }
  testing::TempDir dir_;
};

TEST_F(TumDatasetTest, AssociatesAndLoadsFramesInMetres) {
  TumDataset dataset(dir_.path(), SmallCamera());
  ASSERT_EQ(dataset.size(), 4u);  // the stray depth frame at t=9 has no partner
  for (size_t k = 0; k < dataset.size(); ++k) {
    const RgbdFrame frame = dataset.Load(k);
    EXPECT_NEAR(frame.timestamp, 1.0 + 0.1 * k, 1e-9);
    EXPECT_NEAR(frame.depth_timestamp - frame.timestamp, 0.004, 1e-9);
    ASSERT_EQ(frame.bgr.type(), CV_8UC3);
    ASSERT_EQ(frame.depth.type(), CV_32FC1);
    EXPECT_EQ(frame.bgr.at<cv::Vec3b>(5, 5)[2], 3 * k);
    EXPECT_FLOAT_EQ(frame.depth.at<float>(5, 5), 1.0f + 0.2f * k);
    EXPECT_EQ(frame.depth.at<float>(0, 0), 0.0f);
    EXPECT_EQ(frame.depth.at<float>(0, 1), 0.0f);  // out of range -> missing
  }
}

TEST_F(TumDatasetTest, ExplicitAssociationsFileIsUsed) {
  testing::WriteText(dir_ / "assoc.txt",
                     "1.1 rgb/1.100000.png 1.104 depth/1.104000.png\n"
                     "1.3 rgb/1.300000.png 1.004 depth/1.004000.png\n");
  TumDatasetOptions options;
  options.associations = "assoc.txt";
  TumDataset dataset(dir_.path(), SmallCamera(), options);
  ASSERT_EQ(dataset.size(), 2u);
  EXPECT_FLOAT_EQ(dataset.Load(1).depth.at<float>(5, 5), 1.0f);  // the pairing is the file's
}

TEST_F(TumDatasetTest, MissingFolderAndFiles) {
  EXPECT_EQ(ErrorOf({}, SmallCamera()).substr(0, 10), "(no error)");
  try {
    TumDataset(dir_ / "nope", SmallCamera());
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "dataset folder not found: " + (dir_ / "nope").string());
  }
  std::filesystem::remove(dir_ / "depth.txt");
  EXPECT_EQ(ErrorOf(), "file not found: " + (dir_ / "depth.txt").string());
}

TEST_F(TumDatasetTest, ListedImageThatDoesNotExist) {
  std::filesystem::remove(dir_ / "rgb" / "1.200000.png");
  EXPECT_EQ(ErrorOf(), "listed image not found: " + (dir_ / "rgb" / "1.200000.png").string());
}

TEST_F(TumDatasetTest, MalformedLineNamesFileAndLine) {
  testing::WriteText(dir_ / "rgb.txt", "# x\n1.0 rgb/1.000000.png\n1.1\n");
  EXPECT_EQ(ErrorOf(),
            (dir_ / "rgb.txt").string() + ":3: expected 'timestamp filename', found 1 columns");
  testing::WriteText(dir_ / "rgb.txt", "1.0 rgb/1.000000.png\nabc rgb/1.100000.png\n");
  EXPECT_EQ(ErrorOf(), (dir_ / "rgb.txt").string() + ":2: timestamp 'abc' is not a number");
}

TEST_F(TumDatasetTest, NonIncreasingTimestamps) {
  testing::WriteText(dir_ / "rgb.txt", "1.1 rgb/1.100000.png\n1.0 rgb/1.000000.png\n");
  EXPECT_EQ(ErrorOf(), (dir_ / "rgb.txt").string() +
                           ":2: timestamp 1.0 does not increase over the line before");
}

TEST_F(TumDatasetTest, EmptySequencesAndEmptyAssociation) {
  testing::WriteText(dir_ / "rgb.txt", "# nothing\n");
  EXPECT_EQ(ErrorOf(), (dir_ / "rgb.txt").string() + ": no frames listed");
  testing::WriteText(dir_ / "rgb.txt", "5.0 rgb/1.000000.png\n");
  const std::string message = ErrorOf();
  EXPECT_NE(message.find("no rgb/depth pair within 0.02"), std::string::npos) << message;
  EXPECT_NE(message.find("rgb.txt spans [5.000000, 5.000000]"), std::string::npos) << message;
  EXPECT_NE(message.find("depth.txt spans [1.004000, 9.000000]"), std::string::npos) << message;
}

TEST_F(TumDatasetTest, UndecodableWrongSizeAndEightBitDepth) {
  testing::WriteText(dir_ / "rgb" / "1.000000.png", "not a png");
  EXPECT_EQ(ErrorOf({}, SmallCamera(), 0),
            (dir_ / "rgb" / "1.000000.png").string() + ": cannot decode image");
  cv::imwrite((dir_ / "rgb" / "1.100000.png").string(), cv::Mat(48, 64, CV_8UC3));
  EXPECT_EQ(ErrorOf({}, SmallCamera(), 1), (dir_ / "rgb" / "1.100000.png").string() +
                                               ": image is 64x48, the camera config says 32x24");
  cv::imwrite((dir_ / "depth" / "1.204000.png").string(), cv::Mat(24, 32, CV_8UC3));
  EXPECT_EQ(ErrorOf({}, SmallCamera(), 2),
            (dir_ / "depth" / "1.204000.png").string() +
                ": depth must be a 16-bit single-channel PNG, found 8-bit with 3 channel(s)");
}

// A 16-bit colour PNG (or a depth image listed in rgb.txt) was decoded to 8 bits without a word
// and tracked on.
TEST_F(TumDatasetTest, SixteenBitColourImageIsNamed) {
  cv::imwrite((dir_ / "rgb" / "1.100000.png").string(),
              cv::Mat(24, 32, CV_16UC3, cv::Scalar(1000, 2000, 3000)));
  EXPECT_EQ(ErrorOf({}, SmallCamera(), 1),
            (dir_ / "rgb" / "1.100000.png").string() +
                ": a 16-bit PNG; a colour frame must be an 8-bit colour image (is it a depth "
                "image?)");
  cv::imwrite((dir_ / "rgb" / "1.200000.png").string(), cv::Mat(24, 32, CV_16UC1));
  EXPECT_NE(ErrorOf({}, SmallCamera(), 2).find("1.200000.png: a 16-bit PNG"), std::string::npos);
}

// A last rgb.txt line at 1e308 was dropped (no depth image near it) without a word.
TEST_F(TumDatasetTest, AbsurdTimestampsAreNamedWithFileAndLine) {
  testing::WriteText(dir_ / "rgb.txt",
                     "# color\n1.0 rgb/1.000000.png\n1.1 rgb/1.100000.png\n1e308 rgb/x.png\n");
  EXPECT_EQ(ErrorOf(), (dir_ / "rgb.txt").string() +
                           ":4: timestamp 1e308 is not a time in seconds (beyond +-1e+10 s, the "
                           "year 2286; nanoseconds?)");
  testing::WriteText(dir_ / "assoc.txt", "1.0 rgb/1.000000.png -1e20 depth/1.004000.png\n");
  TumDatasetOptions options;
  options.associations = "assoc.txt";
  EXPECT_NE(ErrorOf(options).find("assoc.txt:1: depth timestamp -1e20 is not a time in seconds"),
            std::string::npos)
      << ErrorOf(options);
}

// A listed image that is a FIFO would block the reader: refused when the dataset is opened, and,
// swapped in after that, when the frame is read.
TEST_F(TumDatasetTest, AListedImageThatIsNoRegularFileIsNamed) {
  const auto image = dir_ / "rgb" / "1.200000.png";
  {
    TumDataset dataset(dir_.path(), SmallCamera());
    std::filesystem::remove(image);
    ASSERT_EQ(mkfifo(image.c_str(), 0600), 0);
    EXPECT_EQ(testing::MessageOf([&] { dataset.Load(2); }),
              image.string() + ": not a regular file");
    EXPECT_NO_THROW(dataset.Load(3));
  }
  EXPECT_EQ(ErrorOf(), image.string() + ": not a regular file");
  std::filesystem::remove(image);
  std::filesystem::create_directory(image);
  EXPECT_EQ(ErrorOf(), image.string() + ": not a regular file");
  // The lists themselves.
  std::filesystem::remove(dir_ / "rgb.txt");
  ASSERT_EQ(mkfifo((dir_ / "rgb.txt").c_str(), 0600), 0);
  EXPECT_EQ(ErrorOf(), (dir_ / "rgb.txt").string() + ": not a regular file");
}

TEST(TumDatasetReal, AssociationReproducesTheShippedAssociationsFile) {
  const auto dir = testing::SharedDir() / "data" / "tum_fr2_desk_50";
  if (!std::filesystem::is_directory(dir)) GTEST_SKIP() << "no " << dir;
  CameraOptions camera;
  camera.fx = 520.9;
  camera.fy = 521.0;
  camera.cx = 325.1;
  camera.cy = 249.7;
  TumDataset by_time(dir, camera);
  TumDatasetOptions options;
  options.associations = "associations.txt";
  TumDataset by_file(dir, camera, options);
  ASSERT_EQ(by_time.size(), 50u);
  ASSERT_EQ(by_file.size(), by_time.size());
  for (size_t k = 0; k < by_time.size(); ++k) {
    EXPECT_EQ(by_time.entries()[k].rgb_path, by_file.entries()[k].rgb_path);
    EXPECT_EQ(by_time.entries()[k].depth_path, by_file.entries()[k].depth_path);
  }
  const RgbdFrame frame = by_time.Load(10);
  EXPECT_EQ(frame.bgr.size(), cv::Size(640, 480));
  int valid = cv::countNonZero(frame.depth > 0);
  EXPECT_GT(valid, 640 * 480 / 2);  // a real Kinect frame: mostly valid depth, in metres
  double max_depth;
  cv::minMaxLoc(frame.depth, nullptr, &max_depth);
  EXPECT_LT(max_depth, 10.0);
}

}  // namespace
}  // namespace sdoslam
