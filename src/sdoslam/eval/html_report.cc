#include "sdoslam/eval/html_report.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "sdoslam/core/atomic_file.h"
#include "sdoslam/core/error.h"
#include "sdoslam/core/regular_file.h"
#include "sdoslam/io/png_reader.h"

namespace sdoslam {
namespace {

// Inline so that the page needs no second file; plain CSS so that it needs no script. Figures
// keep their images' aspect ratio and never grow past their natural size (thumbnails stay sharp).
constexpr const char* kStyle = R"(
body { font-family: sans-serif; margin: 24px auto; max-width: 1200px; padding: 0 16px;
       color: #222; line-height: 1.4; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; }
h2 { font-size: 1.25em; border-bottom: 1px solid #ccc; padding-bottom: 0.2em; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 3px 8px; }
th { background: #f0f0f0; }
td { text-align: right; font-variant-numeric: tabular-nums; }
td:first-child { text-align: left; white-space: nowrap; }
.images { display: flex; flex-wrap: wrap; gap: 12px; align-items: flex-start; }
figure { margin: 0; }
figure img { display: block; max-width: 100%; height: auto; border: 1px solid #ddd; }
.grid figure { width: calc(50% - 6px); }
.full figure { width: 100%; }
.strip figure { max-width: calc(33.33% - 8px); }
figcaption { font-size: 0.85em; color: #555; margin-top: 2px; }
.note { font-size: 0.85em; color: #555; }
pre { background: #f6f6f6; border: 1px solid #ddd; padding: 8px; font-size: 0.8em;
      overflow: auto; max-height: 40em; }
)";

const char* LayoutClass(HtmlImageLayout layout) {
  switch (layout) {
    case HtmlImageLayout::kGrid:
      return "grid";
    case HtmlImageLayout::kFull:
      return "full";
    case HtmlImageLayout::kStrip:
      return "strip";
  }
  return "grid";
}

// A relative path as a URL path: characters a URL treats specially (space, #, ?, %, ...) are
// percent-encoded so that the browser opens the file of that name.
std::string UrlPath(const std::filesystem::path& path) {
  std::string url;
  for (unsigned char c : path.generic_string()) {
    if (std::isalnum(c) || c == '-' || c == '.' || c == '_' || c == '~' || c == '/') {
      url += static_cast<char>(c);
    } else {
      url += fmt::format("%{:02X}", c);
    }
  }
  return url;
}

// Checks that `path` names an existing file inside `folder`, relative to it, and returns it as a
// URL. A page must not point at nothing, nor outside its folder (it would break when moved).
std::string CheckedUrl(const std::filesystem::path& path, const std::filesystem::path& folder,
                       const std::string& section, const char* what) {
  const std::string where =
      fmt::format("report in {}: section '{}': {}", folder.string(), section, what);
  if (path.empty()) throw Error(where + " has no path");
  if (path.has_root_path()) {
    throw Error(
        fmt::format("{} {} is absolute: name it relative to the report's folder so that "
                    "the folder can be moved",
                    where, path.string()));
  }
  for (const auto& part : path) {
    if (part == "..") {
      throw Error(fmt::format("{} {} leaves the report's folder", where, path.string()));
    }
  }
  if (!std::filesystem::is_regular_file(folder / path)) {
    throw Error(fmt::format("{} {} does not exist (looked for {})", where, path.string(),
                            (folder / path).string()));
  }
  return UrlPath(path);
}

std::string ReadWholeFile(const std::filesystem::path& path) {
  std::optional<std::string> text = ReadRegularFileIfExists(path);
  if (!text) throw Error("cannot read " + path.string());
  return std::move(*text);
}

std::string RenderTable(const HtmlTable& table, const std::string& section) {
  std::string out = "<table>\n<tr>";
  for (const auto& h : table.header) out += "<th>" + EscapeHtml(h) + "</th>";
  out += "</tr>\n";
  for (const auto& row : table.rows) {
    if (row.size() != table.header.size()) {
      throw Error(fmt::format("report section '{}': a table row has {} cells for {} columns",
                              section, row.size(), table.header.size()));
    }
    out += "<tr>";
    for (const auto& cell : row) out += "<td>" + EscapeHtml(cell) + "</td>";
    out += "</tr>\n";
  }
  return out + "</table>\n";
}

std::string RenderSection(const HtmlSection& section, const std::filesystem::path& folder) {
  std::string out = "<section>\n<h2>" + EscapeHtml(section.title) + "</h2>\n";
  for (const auto& p : section.paragraphs) out += "<p>" + EscapeHtml(p) + "</p>\n";
  for (const auto& table : section.tables) out += RenderTable(table, section.title);
  if (!section.images.empty()) {
    out += fmt::format("<div class=\"images {}\">\n", LayoutClass(section.layout));
    for (const auto& image : section.images) {
      const std::string src = CheckedUrl(image.src, folder, section.title, "image");
      const std::string alt = image.caption.empty() ? image.src.filename().string() : image.caption;
      std::string img =
          fmt::format("<img src=\"{}\" alt=\"{}\">", EscapeHtml(src), EscapeHtml(alt));
      if (!image.link.empty()) {
        const std::string href = CheckedUrl(image.link, folder, section.title, "link");
        img = fmt::format("<a href=\"{}\">{}</a>", EscapeHtml(href), img);
      }
      out += "<figure>" + img;
      if (!image.caption.empty())
        out += "<figcaption>" + EscapeHtml(image.caption) + "</figcaption>";
      out += "</figure>\n";
    }
    out += "</div>\n";
  }
  for (const auto& note : section.notes) out += "<p class=\"note\">" + EscapeHtml(note) + "</p>\n";
  if (!section.text_file.empty()) {
    const std::string href = CheckedUrl(section.text_file, folder, section.title, "text file");
    out += fmt::format("<p class=\"note\"><a href=\"{}\">{}</a>:</p>\n<pre>{}</pre>\n",
                       EscapeHtml(href), EscapeHtml(section.text_file.generic_string()),
                       EscapeHtml(ReadWholeFile(folder / section.text_file)));
  }
  return out + "</section>\n";
}

std::string Fixed(double value, int decimals) { return fmt::format("{:.{}f}", value, decimals); }

}  // namespace

std::string EscapeHtml(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string RenderHtmlReport(const HtmlReport& report, const std::filesystem::path& folder) {
  std::string out = fmt::format(
      "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
      "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
      "<title>{}</title>\n<style>{}</style>\n</head>\n<body>\n<h1>{}</h1>\n",
      EscapeHtml(report.title), kStyle, EscapeHtml(report.title));
  for (const auto& p : report.intro) out += "<p>" + EscapeHtml(p) + "</p>\n";
  for (const auto& section : report.sections) out += RenderSection(section, folder);
  return out + "</body>\n</html>\n";
}

void WriteHtmlReport(const HtmlReport& report, const std::filesystem::path& path) {
  // Rendered first: a missing input fails before anything is written.
  const std::string html = RenderHtmlReport(report, path.parent_path());
  WriteFileAtomically(path, [&](std::ostream& out) { out << html; });
}

HtmlSection EvaluationSection(const std::vector<EstimateEvaluation>& evaluations,
                              const EvaluationOptions& options) {
  HtmlSection section;
  section.title = "Accuracy";
  const std::string delta = fmt::format("{:g} {}", options.rte.delta,
                                        options.rte.unit == DeltaUnit::kFrames ? "frames" : "s");
  section.paragraphs.push_back(fmt::format(
      "Absolute trajectory error (ATE, after {} alignment) in metres over the matched poses; "
      "relative pose error (RTE) over {}: RMSE of translation (m) and rotation (degrees).",
      ToString(options.ate.alignment), delta));
  HtmlTable table;
  table.header = {"estimate", "matched poses", "ATE rmse",  "mean",    "median",   "std",
                  "min",      "max",           "RTE trans", "RTE rot", "RTE pairs"};
  for (const auto& e : evaluations) {
    const ErrorStats& s = e.ate.translation;
    std::vector<std::string> row = {e.label,          std::to_string(s.count), Fixed(s.rmse, 4),
                                    Fixed(s.mean, 4), Fixed(s.median, 4),      Fixed(s.std, 4),
                                    Fixed(s.min, 4),  Fixed(s.max, 4)};
    if (e.rte) {
      row.push_back(Fixed(e.rte->translation.rmse, 4));
      row.push_back(Fixed(e.rte->rotation.rmse, 3));
      row.push_back(std::to_string(e.rte->translation.count));
    } else {
      row.insert(row.end(), {"n/a", "n/a", "0"});
    }
    table.rows.push_back(std::move(row));
  }
  section.tables.push_back(std::move(table));
  for (const auto& e : evaluations) {
    if (!e.rte) section.notes.push_back(fmt::format("{}: no RTE: {}", e.label, e.rte_note));
    if (e.ate.translation.count < e.estimate_poses) {
      section.notes.push_back(
          fmt::format("{}: {} of {} estimated poses have no ground truth within {} s", e.label,
                      e.estimate_poses - e.ate.translation.count, e.estimate_poses,
                      options.ate.max_time_difference));
    }
  }
  return section;
}

std::vector<size_t> EvenlySpaced(size_t n, size_t count) {
  std::vector<size_t> picked;
  if (n == 0 || count == 0) return picked;
  if (count >= n || count == 1) {
    for (size_t i = 0; i < std::min(n, count); ++i) picked.push_back(i);
    return picked;
  }
  for (size_t k = 0; k < count; ++k) {
    picked.push_back(static_cast<size_t>(
        std::llround(static_cast<double>(k) * static_cast<double>(n - 1) / (count - 1))));
  }
  return picked;
}

void WriteThumbnail(const std::filesystem::path& image, const std::filesystem::path& thumbnail,
                    int width, const std::vector<ThumbnailMark>& marks) {
  const std::string ext = thumbnail.extension().string();
  if (ext != ".jpg" && ext != ".jpeg" && ext != ".png") {
    throw Error("cannot write thumbnail " + thumbnail.string() + ": use a .jpg or .png name");
  }
  if (width < 1) throw Error(fmt::format("thumbnail width must be positive, not {}", width));
  const cv::Mat full = ReadImage(image, cv::IMREAD_COLOR);
  if (full.empty()) throw Error("cannot read image " + image.string());
  cv::Mat small = full;
  if (full.cols > width) {
    const int height = std::max(
        1, static_cast<int>(std::lround(static_cast<double>(full.rows) * width / full.cols)));
    // INTER_AREA averages the pixels each thumbnail pixel covers: no aliasing of the fine
    // outlines into noise.
    cv::resize(full, small, cv::Size(width, height), 0, 0, cv::INTER_AREA);
  }
  const double scale = static_cast<double>(small.cols) / full.cols;
  constexpr int kShift = 2;  // quarter-pixel centres and radii
  for (const ThumbnailMark& mark : marks) {
    const cv::Point centre(static_cast<int>(std::lround(mark.at.x * scale * (1 << kShift))),
                           static_cast<int>(std::lround(mark.at.y * scale * (1 << kShift))));
    // The dark rim keeps a dot visible on a tint of its own hue (red on orange).
    cv::circle(small, centre, 10, cv::Scalar(0, 0, 0), -1, cv::LINE_AA, kShift);  // radius 2.5
    cv::circle(small, centre, 6,
               cv::Scalar(mark.rgb & 0xff, (mark.rgb >> 8) & 0xff, (mark.rgb >> 16) & 0xff), -1,
               cv::LINE_AA, kShift);  // radius 1.5
  }
  const std::vector<int> params = {cv::IMWRITE_JPEG_QUALITY, 85};
  WriteFileAtomically(thumbnail, [&](const std::filesystem::path& tmp) {
    return cv::imwrite(tmp.string(), small, params);
  });
}

}  // namespace sdoslam
