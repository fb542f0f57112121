#include "sdoslam/dynamic/lab.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace sdoslam {
namespace {

// The CIE f(t) of L*a*b*: the cube root above (6/29)³, a line below it.
double LabF(double t) { return t > 0.008856 ? std::cbrt(t) : 7.787 * t + 16.0 / 116.0; }

struct LabTables {
  static constexpr int kSteps = 4096;  // f sampled over t in [0, 1]; linear in between
  std::array<float, 256> linear{};     // sRGB 8-bit value -> linear intensity
  // f at step i and its rise to step i + 1, side by side (one cache line for both); one entry
  // more than the steps, which t = 1 reaches.
  std::array<std::array<float, 2>, kSteps + 1> f{};
  LabTables() {
    for (int i = 0; i < 256; ++i) {
      const double x = i / 255.0;
      linear[static_cast<size_t>(i)] =
          static_cast<float>(x <= 0.04045 ? x / 12.92 : std::pow((x + 0.055) / 1.055, 2.4));
    }
    for (size_t i = 0; i < f.size(); ++i) {
      const double t = static_cast<double>(i) / kSteps;
      f[i] = {static_cast<float>(LabF(t)), static_cast<float>(LabF(t + 1.0 / kSteps) - LabF(t))};
    }
  }
  // t >= 0 always (a sum of non-negative terms); t <= 1 up to rounding.
  float F(float t) const {
    const float x = std::min(t, 1.0f) * kSteps;
    const auto i = static_cast<size_t>(x);
    return f[i][0] + (x - static_cast<float>(i)) * f[i][1];
  }
};

const LabTables& Tables() {
  static const LabTables tables;
  return tables;
}

cv::Vec3f LabOf(const LabTables& tables, const cv::Vec3b& bgr) {
  // sRGB primaries to XYZ (D65), with X and Z divided by the white point's (0.950456, 1.088754).
  constexpr float kX[3] = {0.412453f / 0.950456f, 0.357580f / 0.950456f, 0.180423f / 0.950456f};
  constexpr float kY[3] = {0.212671f, 0.715160f, 0.072169f};
  constexpr float kZ[3] = {0.019334f / 1.088754f, 0.119193f / 1.088754f, 0.950227f / 1.088754f};
  const float b = tables.linear[bgr[0]], g = tables.linear[bgr[1]], r = tables.linear[bgr[2]];
  const float fx = tables.F(kX[0] * r + kX[1] * g + kX[2] * b);
  const float fy = tables.F(kY[0] * r + kY[1] * g + kY[2] * b);
  const float fz = tables.F(kZ[0] * r + kZ[1] * g + kZ[2] * b);
  return {116.0f * fy - 16.0f, 500.0f * (fx - fy), 200.0f * (fy - fz)};
}

}  // namespace

void BgrToLab(const cv::Mat& bgr, cv::Mat* lab) {
  CV_Assert(bgr.type() == CV_8UC3);
  const LabTables& tables = Tables();
  lab->create(bgr.size(), CV_32FC3);
  for (int y = 0; y < bgr.rows; ++y) {
    const cv::Vec3b* in = bgr.ptr<cv::Vec3b>(y);
    cv::Vec3f* out = lab->ptr<cv::Vec3f>(y);
    for (int x = 0; x < bgr.cols; ++x) out[x] = LabOf(tables, in[x]);
  }
}

cv::Vec3f BgrPixelToLab(const cv::Vec3b& bgr) { return LabOf(Tables(), bgr); }

}  // namespace sdoslam
