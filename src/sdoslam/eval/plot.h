#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

namespace sdoslam {

// A minimal 2-D line plot written as PNG (OpenCV drawing) or SVG (plain text), chosen by the
// file extension. Hand-written because Debian offers no small, well-kept C++ plotting library;
// the evaluation needs only lines, segments, axes with ticks and a legend.
struct PlotSeries {
  std::string label;  // shown in the legend when not empty
  std::vector<Eigen::Vector2d> points;
  unsigned rgb = 0x1f77b4;  // colour as 0xRRGGBB
  double line_width = 1.5;
  bool as_segments = false;  // points are pairs (p0 p1 p2 p3 ...) of separate segments
};

struct Plot {
  std::string title;
  std::string x_label;
  std::string y_label;
  bool equal_aspect = false;  // one metre is as long on both axes (top views)
  std::vector<PlotSeries> series;
};

// Writes `plot` to `path` (.png or .svg), atomically. Throws Error for another extension.
void SavePlot(const Plot& plot, const std::filesystem::path& path, int width = 960,
              int height = 720);

// Tick positions covering [lo, hi]: multiples of 1, 2 or 5 × 10^k, about `target` of them.
std::vector<double> NiceTicks(double lo, double hi, int target = 6);

}  // namespace sdoslam
