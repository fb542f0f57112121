#pragma once

#include <opencv2/core.hpp>

namespace sdoslam {

// CIE L*a*b* (D65) of an 8-bit sRGB image in BGR order, in the convention of
// cv::cvtColor(COLOR_BGR2Lab) on the image scaled to [0, 1] floats: CV_32FC3, L in [0, 100], a
// and b in about [-127, 127]. Within 0.01 of the CIE formulas (OpenCV's interpolated tables are
// up to 0.4 off them; a test checks both).
//
// Written here because OpenCV's first Lab conversion in a process builds its interpolation
// tables in software floating point: 140-270 ms of one core (docs/performance.md), paid by the
// first frame of every run. This one needs a 256-entry table for the sRGB curve and one of
// 4,097 for the cube root, made in microseconds.
void BgrToLab(const cv::Mat& bgr, cv::Mat* lab);

// The same conversion of one pixel, for callers that need a few pixels' colours.
cv::Vec3f BgrPixelToLab(const cv::Vec3b& bgr);

}  // namespace sdoslam
