#pragma once

#include <filesystem>
#include <opencv2/core.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "sdoslam/eval/report.h"

namespace sdoslam {

// A results page a user opens in any browser: one HTML file with inline CSS, no JavaScript and no
// network, whose images and links are files next to it, named by paths relative to its folder,
// so that the folder can be moved or archived as a whole. The inputs are plain (text, tables and
// file paths) so that the page can be written and tested without running SLAM.

// An image shown on the page. Paths are relative to the report's folder.
struct HtmlImage {
  std::filesystem::path src;
  std::string caption;         // below the image; may be empty
  std::filesystem::path link;  // optional: what clicking the image opens (a larger version)
};

struct HtmlTable {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;  // each as long as the header
};

// How a section's images are laid out.
enum class HtmlImageLayout {
  kGrid,   // two per row, each half the page wide (plots)
  kFull,   // one per row, as wide as the page
  kStrip,  // side by side at their own size, wrapping (thumbnails)
};

struct HtmlSection {
  std::string title;
  std::vector<std::string> paragraphs;  // plain text: escaped, never interpreted as HTML
  std::vector<HtmlTable> tables;
  std::vector<HtmlImage> images;
  HtmlImageLayout layout = HtmlImageLayout::kGrid;
  std::vector<std::string> notes;  // small print after the images
  // Optional, relative to the report's folder: a text file (a config) shown verbatim in a <pre>,
  // escaped, with a link to the file itself.
  std::filesystem::path text_file;
};

struct HtmlReport {
  std::string title;
  std::vector<std::string> intro;  // paragraphs under the title
  std::vector<HtmlSection> sections;
};

// The page as text. Every image, link and text file must exist relative to `folder` (the folder
// the page will be written to): a page that points at nothing is a broken result, so a missing
// file, an absolute path or one leaving the folder (..) throws Error naming the section and the
// file. A table row whose length differs from its header throws Error too.
std::string RenderHtmlReport(const HtmlReport& report, const std::filesystem::path& folder);

// Renders the page for `path`'s folder and writes it atomically (an earlier report is replaced
// only by a complete one).
void WriteHtmlReport(const HtmlReport& report, const std::filesystem::path& path);

// `text` with & < > " ' replaced by entities: safe in element content and quoted attributes.
std::string EscapeHtml(std::string_view text);

// The ATE/RTE table FormatTable prints, as a section: one row per estimate, with the notes on
// missing RTE and unmatched poses.
HtmlSection EvaluationSection(const std::vector<EstimateEvaluation>& evaluations,
                              const EvaluationOptions& options);

// `count` indices spread evenly over [0, n), first and last included (fewer when n < count):
// which frames of a run a strip of thumbnails shows.
std::vector<size_t> EvenlySpaced(size_t n, size_t count);

// A dot drawn on a thumbnail after scaling, at `at` in the full image's pixels: markers a few
// pixels wide in the full image (features) blur into their surroundings when scaled down.
struct ThumbnailMark {
  cv::Point2f at;
  unsigned rgb = 0;  // 0xRRGGBB
};

// Writes `image` scaled down to `width` pixels wide (never up) to `thumbnail` (.jpg or .png),
// atomically, so that a page shows a handful of frames without loading full-size images. `marks`
// are drawn on the result as dots of radius 1.5 thumbnail pixels with a dark rim.
// Throws Error when `image` cannot be read and IoError when `thumbnail` cannot be written.
void WriteThumbnail(const std::filesystem::path& image, const std::filesystem::path& thumbnail,
                    int width, const std::vector<ThumbnailMark>& marks = {});

}  // namespace sdoslam
