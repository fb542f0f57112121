#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <ostream>
#include <string>
#include <vector>

namespace sdoslam {

// A point of a coloured cloud: world coordinates (metres) and 8-bit RGB.
struct ColoredPoint {
  Eigen::Vector3f position = Eigen::Vector3f::Zero();
  std::array<uint8_t, 3> rgb = {0, 0, 0};
};

// Writes a binary little-endian PLY (vertex: float x, y, z; uchar red, green, blue), the form
// MeshLab, CloudCompare, Open3D and PCL all read. `comment` lines (no newlines) go in the header.
// Written by hand: no Debian package here writes PLY (PCL would be a large dependency for 40
// lines).
void WritePly(std::ostream& out, const std::vector<ColoredPoint>& points,
              const std::vector<std::string>& comments = {});

// Reads a PLY written by WritePly, or any ASCII or binary little-endian PLY whose vertex element
// has float (or double) x, y, z and uchar red, green, blue, in any order, among other
// properties of fixed size. Faces and other elements after the vertices are ignored. Throws
// Error naming the file and what is wrong.
std::vector<ColoredPoint> ReadPly(const std::filesystem::path& path);

}  // namespace sdoslam
