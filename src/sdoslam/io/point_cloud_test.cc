#include "sdoslam/io/point_cloud.h"

#include <gtest/gtest.h>

#include <fstream>

#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

std::string PlyErrorOf(const std::filesystem::path& path) {
  return testing::MessageOf([&] { ReadPly(path); });
}

TEST(PointCloud, BinaryRoundTripKeepsPositionsAndColours) {
  testing::TempDir dir;
  std::vector<ColoredPoint> points;
  for (int k = 0; k < 100; ++k) {
    ColoredPoint p;
    p.position = Eigen::Vector3f(0.01f * k, -1.5f + 0.3f * k, 2.0f / (k + 1));
    p.rgb = {static_cast<uint8_t>(k), static_cast<uint8_t>(255 - k), static_cast<uint8_t>(2 * k)};
    points.push_back(p);
  }
  const auto path = dir.path() / "map.ply";
  {
    std::ofstream out(path, std::ios::binary);
    WritePly(out, points, {"made by a test"});
  }
  // 15 bytes per vertex after the header.
  std::ifstream in(path, std::ios::binary);
  const std::string content((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const size_t header_end = content.find("end_header\n") + std::string("end_header\n").size();
  EXPECT_EQ(content.size() - header_end, 100u * 15u);
  EXPECT_NE(content.find("comment made by a test\n"), std::string::npos);

  const std::vector<ColoredPoint> read = ReadPly(path);
  ASSERT_EQ(read.size(), points.size());
  for (size_t k = 0; k < points.size(); ++k) {
    EXPECT_EQ(read[k].position, points[k].position) << k;
    EXPECT_EQ(read[k].rgb, points[k].rgb) << k;
  }
}

TEST(PointCloud, ReadsAsciiWithOtherPropertiesInAnyOrder) {
  testing::TempDir dir;
  const auto path = dir.path() / "ascii.ply";
  testing::WriteText(
      path,
      "ply\nformat ascii 1.0\nelement vertex 2\nproperty uchar blue\nproperty double z\n"
      "property float nx\nproperty float x\nproperty float y\nproperty uchar green\n"
      "property uchar red\nelement face 0\nproperty list uchar int vertex_indices\n"
      "end_header\n"
      "3 1.5 0 0.25 -2 2 1\n"
      "30 -7 0 4 5 20 10\n");
  const std::vector<ColoredPoint> read = ReadPly(path);
  ASSERT_EQ(read.size(), 2u);
  EXPECT_EQ(read[0].position, Eigen::Vector3f(0.25f, -2.0f, 1.5f));
  EXPECT_EQ(read[0].rgb, (std::array<uint8_t, 3>{1, 2, 3}));
  EXPECT_EQ(read[1].position, Eigen::Vector3f(4.0f, 5.0f, -7.0f));
  EXPECT_EQ(read[1].rgb, (std::array<uint8_t, 3>{10, 20, 30}));
}

TEST(PointCloud, MalformedFilesNameTheFileAndTheProblem) {
  testing::TempDir dir;
  EXPECT_NE(PlyErrorOf(dir.path() / "absent.ply").find("absent.ply: cannot open"),
            std::string::npos);

  const auto not_ply = dir.path() / "not.ply";
  testing::WriteText(not_ply, "solid cube\n");
  EXPECT_NE(PlyErrorOf(not_ply).find("not.ply:1: not a PLY file"), std::string::npos)
      << PlyErrorOf(not_ply);

  const auto no_colour = dir.path() / "no_colour.ply";
  testing::WriteText(no_colour,
                     "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                     "property float z\nend_header\n1 2 3\n");
  EXPECT_NE(PlyErrorOf(no_colour).find("no property red"), std::string::npos)
      << PlyErrorOf(no_colour);

  const auto big_endian = dir.path() / "big.ply";
  testing::WriteText(big_endian,
                     "ply\nformat binary_big_endian 1.0\nelement vertex 0\nend_header\n");
  EXPECT_NE(PlyErrorOf(big_endian).find("big.ply:2: format binary_big_endian"), std::string::npos)
      << PlyErrorOf(big_endian);

  // A binary file cut short: the header promises 2 vertices, 1 and a half are there.
  const auto truncated = dir.path() / "truncated.ply";
  {
    std::ofstream out(truncated, std::ios::binary);
    WritePly(out, std::vector<ColoredPoint>(2));
  }
  std::filesystem::resize_file(truncated, std::filesystem::file_size(truncated) - 8);
  EXPECT_NE(PlyErrorOf(truncated).find("truncated: vertex 1 of 2"), std::string::npos)
      << PlyErrorOf(truncated);

  const auto no_end = dir.path() / "no_end.ply";
  testing::WriteText(no_end, "ply\nformat ascii 1.0\nelement vertex 1\n");
  EXPECT_NE(PlyErrorOf(no_end).find("no end_header"), std::string::npos) << PlyErrorOf(no_end);
}

}  // namespace
}  // namespace sdoslam
