#include "sdoslam/eval/plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "sdoslam/core/atomic_file.h"
#include "sdoslam/core/error.h"

namespace sdoslam {
namespace {

enum class Anchor { kLeft, kCentre, kRight };

// The drawing operations the layout needs; one layout, two back ends.
class Canvas {
 public:
  virtual ~Canvas() = default;
  virtual void Line(const std::vector<cv::Point2d>& points, unsigned rgb, double width) = 0;
  virtual void Text(cv::Point2d at, const std::string& text, double size, Anchor anchor,
                    bool vertical = false) = 0;
  virtual double TextWidth(const std::string& text, double size) const = 0;
};

class PngCanvas : public Canvas {
 public:
  PngCanvas(int w, int h) : image_(h, w, CV_8UC3, cv::Scalar(255, 255, 255)) {}
  void Line(const std::vector<cv::Point2d>& points, unsigned rgb, double width) override {
    std::vector<cv::Point> p;
    constexpr int kShift = 4;  // sub-pixel precision for anti-aliased lines
    for (const auto& q : points) p.emplace_back(cvRound(q.x * 16), cvRound(q.y * 16));
    cv::polylines(image_, p, false, Bgr(rgb), std::max(1, static_cast<int>(width)), cv::LINE_AA,
                  kShift);
  }
  void Text(cv::Point2d at, const std::string& text, double size, Anchor anchor,
            bool vertical) override {
    const double scale = FontScale(size);
    int baseline = 0;
    const cv::Size extent = cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, scale, 1, &baseline);
    const double shift = anchor == Anchor::kLeft ? 0 : anchor == Anchor::kCentre ? 0.5 : 1.0;
    if (!vertical) {
      cv::putText(image_, text, cv::Point(cvRound(at.x - shift * extent.width), cvRound(at.y)),
                  cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
      return;
    }
    cv::Mat strip(extent.height + baseline + 2, extent.width + 2, CV_8UC3,
                  cv::Scalar(255, 255, 255));
    cv::putText(strip, text, cv::Point(1, extent.height + 1), cv::FONT_HERSHEY_SIMPLEX, scale,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    cv::rotate(strip, strip, cv::ROTATE_90_COUNTERCLOCKWISE);
    const int x = cvRound(at.x - strip.cols);
    const int y = cvRound(at.y - (1.0 - shift) * strip.rows);
    const cv::Rect roi =
        cv::Rect(x, y, strip.cols, strip.rows) & cv::Rect(0, 0, image_.cols, image_.rows);
    if (roi.area() > 0)
      strip(cv::Rect(roi.x - x, roi.y - y, roi.width, roi.height)).copyTo(image_(roi));
  }
  double TextWidth(const std::string& text, double size) const override {
    int baseline = 0;
    return cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, FontScale(size), 1, &baseline).width;
  }
  const cv::Mat& image() const { return image_; }

 private:
  static double FontScale(double size) { return size / 40.0; }
  static cv::Scalar Bgr(unsigned rgb) {
    return cv::Scalar(rgb & 0xff, (rgb >> 8) & 0xff, (rgb >> 16) & 0xff);
  }
  cv::Mat image_;
};

class SvgCanvas : public Canvas {
 public:
  SvgCanvas(int w, int h) {
    out_ << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << w << "\" height=\"" << h
         << "\" viewBox=\"0 0 " << w << ' ' << h
         << "\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  }
  void Line(const std::vector<cv::Point2d>& points, unsigned rgb, double width) override {
    char colour[8];
    std::snprintf(colour, sizeof(colour), "#%06x", rgb & 0xffffff);
    out_ << "<polyline fill=\"none\" stroke=\"" << colour << "\" stroke-width=\"" << width
         << "\" points=\"";
    for (const auto& p : points) out_ << Number(p.x) << ',' << Number(p.y) << ' ';
    out_ << "\"/>\n";
  }
  void Text(cv::Point2d at, const std::string& text, double size, Anchor anchor,
            bool vertical) override {
    const char* a = anchor == Anchor::kLeft     ? "start"
                    : anchor == Anchor::kCentre ? "middle"
                                                : "end";
    out_ << "<text x=\"" << Number(at.x) << "\" y=\"" << Number(at.y)
         << "\" font-family=\"sans-serif\" font-size=\"" << Number(size * 0.7)
         << "\" text-anchor=\"" << a << '"';
    if (vertical)
      out_ << " transform=\"rotate(-90 " << Number(at.x) << ' ' << Number(at.y) << ")\"";
    out_ << '>' << Escape(text) << "</text>\n";
  }
  double TextWidth(const std::string& text, double size) const override {
    return 0.55 * size * 0.7 * static_cast<double>(text.size());  // average sans-serif advance
  }
  std::string Finish() { return out_.str() + "</svg>\n"; }

 private:
  static std::string Number(double v) {
    char b[32];
    std::snprintf(b, sizeof(b), "%.2f", v);
    return b;
  }
  static std::string Escape(const std::string& s) {
    std::string r;
    for (char c : s) {
      if (c == '<')
        r += "&lt;";
      else if (c == '>')
        r += "&gt;";
      else if (c == '&')
        r += "&amp;";
      else
        r += c;
    }
    return r;
  }
  std::ostringstream out_;
};

std::string TickLabel(double v, double step) {
  char b[32];
  const int decimals = std::max(0, static_cast<int>(-std::floor(std::log10(step) + 1e-9)));
  std::snprintf(b, sizeof(b), "%.*f", decimals, std::abs(v) < step * 1e-6 ? 0.0 : v);
  return b;
}

// The series' bounds, 5 % wider on each side (a unit square when there is no data).
struct Bounds {
  double x0, x1, y0, y1;
};
Bounds PaddedDataBounds(const Plot& plot) {
  double x0 = std::numeric_limits<double>::infinity(), x1 = -x0, y0 = x0, y1 = -x0;
  for (const auto& s : plot.series) {
    for (const auto& p : s.points) {
      x0 = std::min(x0, p.x());
      x1 = std::max(x1, p.x());
      y0 = std::min(y0, p.y());
      y1 = std::max(y1, p.y());
    }
  }
  if (!std::isfinite(x0)) x0 = 0, x1 = 1, y0 = 0, y1 = 1;
  auto pad = [](double& lo, double& hi) {
    const double span = hi - lo;
    const double margin = span > 0 ? 0.05 * span : std::max(1e-3, 0.05 * std::abs(lo));
    lo -= margin;
    hi += margin;
  };
  pad(x0, x1);
  pad(y0, y1);

  return {x0, x1, y0, y1};
}

void Draw(const Plot& plot, Canvas& canvas, int width, int height) {
  auto [x0, x1, y0, y1] = PaddedDataBounds(plot);
  const double left = 100, right = width - 30, top = 50, bottom = height - 70;
  if (plot.equal_aspect) {  // widen the narrower axis so metres are square
    const double sx = (x1 - x0) / (right - left), sy = (y1 - y0) / (bottom - top);
    if (sx > sy) {
      const double c = 0.5 * (y0 + y1), half = 0.5 * sx * (bottom - top);
      y0 = c - half, y1 = c + half;
    } else {
      const double c = 0.5 * (x0 + x1), half = 0.5 * sy * (right - left);
      x0 = c - half, x1 = c + half;
    }
  }
  auto to_px = [&](const Eigen::Vector2d& p) {
    return cv::Point2d(left + (p.x() - x0) / (x1 - x0) * (right - left),
                       bottom - (p.y() - y0) / (y1 - y0) * (bottom - top));
  };

  // Axes, grid ticks and labels.
  constexpr unsigned kAxis = 0x000000, kGrid = 0xdddddd;
  const auto xt = NiceTicks(x0, x1), yt = NiceTicks(y0, y1);
  for (double x : xt) {
    const double px = to_px({x, y0}).x;
    canvas.Line({{px, top}, {px, bottom}}, kGrid, 1);
    canvas.Text({px, bottom + 22}, TickLabel(x, xt.size() > 1 ? xt[1] - xt[0] : 1), 18,
                Anchor::kCentre);
  }
  for (double y : yt) {
    const double py = to_px({x0, y}).y;
    canvas.Line({{left, py}, {right, py}}, kGrid, 1);
    canvas.Text({left - 8, py + 6}, TickLabel(y, yt.size() > 1 ? yt[1] - yt[0] : 1), 18,
                Anchor::kRight);
  }
  canvas.Line({{left, top}, {left, bottom}, {right, bottom}, {right, top}, {left, top}}, kAxis, 1);
  canvas.Text({0.5 * (left + right), 30}, plot.title, 24, Anchor::kCentre);
  canvas.Text({0.5 * (left + right), bottom + 52}, plot.x_label, 20, Anchor::kCentre);
  canvas.Text({22, 0.5 * (top + bottom)}, plot.y_label, 20, Anchor::kCentre, true);

  // Data, then legend (top right, inside the frame).
  for (const auto& s : plot.series) {
    if (s.as_segments) {
      for (size_t k = 0; k + 1 < s.points.size(); k += 2) {
        canvas.Line({to_px(s.points[k]), to_px(s.points[k + 1])}, s.rgb, s.line_width);
      }
    } else if (!s.points.empty()) {
      std::vector<cv::Point2d> px;
      for (const auto& p : s.points) px.push_back(to_px(p));
      canvas.Line(px, s.rgb, s.line_width);
    }
  }
  double legend_width = 0;
  for (const auto& s : plot.series)
    legend_width = std::max(legend_width, canvas.TextWidth(s.label, 18));
  const double text_x = right - 10 - legend_width;
  double ly = top + 22;
  for (const auto& s : plot.series) {
    if (s.label.empty()) continue;
    canvas.Line({{text_x - 38, ly - 5}, {text_x - 8, ly - 5}}, s.rgb, std::max(2.0, s.line_width));
    canvas.Text({text_x, ly}, s.label, 18, Anchor::kLeft);
    ly += 22;
  }
}

}  // namespace

std::vector<double> NiceTicks(double lo, double hi, int target) {
  if (!(hi > lo)) return {lo};
  const double raw = (hi - lo) / std::max(1, target);
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  double step = magnitude;
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    step = m * magnitude;
    if (step >= raw) break;
  }
  std::vector<double> ticks;
  for (double t = std::ceil(lo / step - 1e-9) * step; t <= hi + 1e-9 * step; t += step) {
    ticks.push_back(t);
  }
  return ticks;
}

void SavePlot(const Plot& plot, const std::filesystem::path& path, int width, int height) {
  const std::string ext = path.extension().string();
  if (ext == ".png") {
    PngCanvas canvas(width, height);
    Draw(plot, canvas, width, height);
    WriteFileAtomically(path, [&](const std::filesystem::path& tmp) {
      return cv::imwrite(tmp.string(), canvas.image());
    });
  } else if (ext == ".svg") {
    SvgCanvas canvas(width, height);
    Draw(plot, canvas, width, height);
    const std::string svg = canvas.Finish();
    WriteFileAtomically(path, [&](std::ostream& out) { out << svg; });
  } else {
    throw Error("cannot write plot " + path.string() + ": use a .png or .svg name");
  }
}

}  // namespace sdoslam
