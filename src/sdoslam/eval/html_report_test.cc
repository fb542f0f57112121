#include "sdoslam/eval/html_report.h"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/testing/html_references.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

size_t Count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

void WriteImage(const std::filesystem::path& path, cv::Size size, cv::Scalar bgr) {
  std::filesystem::create_directories(path.parent_path());
  ASSERT_TRUE(cv::imwrite(path.string(), cv::Mat(size, CV_8UC3, bgr)));
}

// A report like the demo's: plots, a strip of thumbnails linking to full frames, a config.
HtmlReport ExampleReport(const testing::TempDir& dir) {
  WriteImage(dir / "plots" / "run_top.png", {64, 48}, {255, 255, 255});
  // A name a URL cannot carry as is: the space and '#' must be escaped or the browser asks for
  // "frames/frame 1" with fragment "2.png".
  WriteImage(dir / "frames" / "frame 1#2.png", {64, 48}, {0, 200, 0});
  WriteImage(dir / "thumbs" / "f1.jpg", {32, 24}, {0, 200, 0});
  testing::WriteText(dir / "run" / "config.yaml", "mode: sdo\n");
  HtmlReport report;
  report.title = "demo";
  report.intro = {"what was run"};
  HtmlSection plots;
  plots.title = "Trajectories";
  plots.images = {{"plots/run_top.png", "run", ""}};
  HtmlSection strip;
  strip.title = "Overlays";
  strip.layout = HtmlImageLayout::kStrip;
  strip.images = {{"thumbs/f1.jpg", "frame 1", "frames/frame 1#2.png"}};
  HtmlSection config;
  config.title = "Config";
  config.text_file = "run/config.yaml";
  report.sections = {plots, strip, config};
  return report;
}

TEST(HtmlReport, ReferencesOnlyFilesThatExistRelativeToTheReport) {
  testing::TempDir dir;
  const HtmlReport report = ExampleReport(dir);
  WriteHtmlReport(report, dir / "report.html");
  const std::string html = testing::ReadText(dir / "report.html");
  const auto files = testing::ReferencedFiles(html);
  // Three images' src, the link to the full frame, the link to the config.
  EXPECT_EQ(files.size(), 4u) << html;
  for (const auto& f : files) {
    EXPECT_FALSE(std::filesystem::path(f).is_absolute()) << f;
    EXPECT_TRUE(std::filesystem::is_regular_file(dir / f)) << f << " in\n" << html;
  }
  EXPECT_NE(std::find(files.begin(), files.end(), "frames/frame 1#2.png"), files.end());
  EXPECT_EQ(Count(html, "<img "), 2u);
  // Self-contained: nothing fetched from the network, nothing to run.
  EXPECT_EQ(html.find("://"), std::string::npos);
  EXPECT_EQ(html.find("<script"), std::string::npos);
  EXPECT_EQ(html.find("<link"), std::string::npos);
  // The config is shown, not only linked.
  EXPECT_NE(html.find("<pre>mode: sdo\n</pre>"), std::string::npos) << html;
}

TEST(HtmlReport, EscapesEveryText) {
  testing::TempDir dir;
  HtmlReport report = ExampleReport(dir);
  testing::WriteText(dir / "run" / "config.yaml",
                     "detector: \"<script>alert('x')</script>\"\nnote: a & b\n");
  report.title = "<b>title</b>";
  report.intro = {"<i>intro</i>"};
  report.sections[0].paragraphs = {"x < y && y > z"};
  report.sections[0].images[0].caption = "say \"cheese\" <img src=x>";
  report.sections[0].tables = {{{"<th>"}, {{"<td>"}}}};
  report.sections[1].notes = {"<hr>"};
  const std::string html = RenderHtmlReport(report, dir.path());
  for (const char* raw : {"<script>", "<b>", "<i>", "<th><th>", "<td><td>", "<hr>", "<img src=x>",
                          "a & b", "x < y"}) {
    EXPECT_EQ(html.find(raw), std::string::npos) << raw << " appears raw in\n" << html;
  }
  EXPECT_NE(html.find("&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt;"), std::string::npos);
  EXPECT_NE(html.find("a &amp; b"), std::string::npos);
  EXPECT_NE(html.find("x &lt; y &amp;&amp; y &gt; z"), std::string::npos);
  // A quote in a caption does not end the alt attribute early.
  EXPECT_NE(html.find("alt=\"say &quot;cheese&quot; &lt;img src=x&gt;\""), std::string::npos)
      << html;
  EXPECT_EQ(EscapeHtml("<a href='x'>&</a>"), "&lt;a href=&#39;x&#39;&gt;&amp;&lt;/a&gt;");
}

TEST(HtmlReport, MissingOrMisplacedInputsAreNamedAndNothingIsWritten) {
  testing::TempDir dir;
  const HtmlReport good = ExampleReport(dir);
  testing::WriteText(dir / "report.html", "earlier report");
  auto message_of = [&](const HtmlReport& report) {
    return testing::MessageOf([&] { WriteHtmlReport(report, dir / "report.html"); });
  };

  HtmlReport r = good;
  r.sections[1].images[0].src = "thumbs/gone.jpg";
  std::string m = message_of(r);
  EXPECT_NE(m.find("thumbs/gone.jpg"), std::string::npos) << m;
  EXPECT_NE(m.find("'Overlays'"), std::string::npos) << m;
  EXPECT_NE(m.find("does not exist"), std::string::npos) << m;

  r = good;
  r.sections[1].images[0].link = "frames/gone.png";
  EXPECT_NE(message_of(r).find("frames/gone.png"), std::string::npos);

  r = good;
  r.sections[2].text_file = "run/gone.yaml";
  EXPECT_NE(message_of(r).find("run/gone.yaml"), std::string::npos);

  r = good;
  r.sections[0].images[0].src = dir / "plots" / "run_top.png";  // exists, but absolute
  m = message_of(r);
  EXPECT_NE(m.find("is absolute"), std::string::npos) << m;

  r = good;
  r.sections[0].images[0].src = "../" + dir.path().filename().string() + "/plots/run_top.png";
  m = message_of(r);
  EXPECT_NE(m.find("leaves the report's folder"), std::string::npos) << m;

  r = good;
  r.sections[0].tables = {{{"a", "b"}, {{"only one"}}}};
  m = message_of(r);
  EXPECT_NE(m.find("1 cells for 2 columns"), std::string::npos) << m;

  // None of these replaced the earlier report; the good one does.
  EXPECT_EQ(testing::ReadText(dir / "report.html"), "earlier report");
  EXPECT_EQ(message_of(good), "(no error)");
  EXPECT_NE(testing::ReadText(dir / "report.html"), "earlier report");
}

TEST(HtmlReport, EvaluationSectionHasOneRowPerEstimate) {
  Trajectory gt;
  for (int k = 0; k < 60; ++k) {
    StampedPose p;
    p.timestamp = k / 30.0;
    p.T_world_camera.translation() = Eigen::Vector3d(0.01 * k, std::sin(0.1 * k), 0);
    gt.push_back(p);
  }
  Trajectory off = gt;
  for (size_t k = 0; k < off.size(); k += 2) off[k].T_world_camera.translation().z() += 0.01;
  const EvaluationOptions options;
  const HtmlSection s = EvaluationSection(
      {EvaluateEstimate(gt, gt, "perfect", options), EvaluateEstimate(gt, off, "<noisy>", options)},
      options);
  ASSERT_EQ(s.tables.size(), 1u);
  const HtmlTable& t = s.tables[0];
  ASSERT_EQ(t.rows.size(), 2u);
  EXPECT_EQ(t.header[2], "ATE rmse");
  EXPECT_EQ(t.rows[0][0], "perfect");
  EXPECT_EQ(t.rows[0][1], "60");
  EXPECT_EQ(t.rows[0][2], "0.0000");
  EXPECT_EQ(t.rows[1][0], "<noisy>");  // escaped when rendered, not here
  // Half the poses off by 1 cm: the aligned RMSE is about 5 mm.
  EXPECT_NEAR(std::stod(t.rows[1][2]), 0.005, 0.001);
  for (const auto& row : t.rows) EXPECT_EQ(row.size(), t.header.size());
}

TEST(EvenlySpaced, SpansFirstToLast) {
  EXPECT_EQ(EvenlySpaced(150, 6), (std::vector<size_t>{0, 30, 60, 89, 119, 149}));
  EXPECT_EQ(EvenlySpaced(40, 6), (std::vector<size_t>{0, 8, 16, 23, 31, 39}));
  EXPECT_EQ(EvenlySpaced(3, 6), (std::vector<size_t>{0, 1, 2}));
  EXPECT_EQ(EvenlySpaced(10, 1), (std::vector<size_t>{0}));
  EXPECT_TRUE(EvenlySpaced(0, 6).empty());
  EXPECT_TRUE(EvenlySpaced(10, 0).empty());
}

TEST(WriteThumbnail, ScalesDownKeepingAspectAndColour) {
  testing::TempDir dir;
  WriteImage(dir / "full.png", {640, 480}, {0, 200, 0});
  WriteThumbnail(dir / "full.png", dir / "t" / "small.jpg", 160);
  const cv::Mat small = cv::imread((dir / "t" / "small.jpg").string());
  ASSERT_EQ(small.size(), cv::Size(160, 120));
  const cv::Vec3b centre = small.at<cv::Vec3b>(60, 80);
  EXPECT_NEAR(centre[1], 200, 8);
  EXPECT_LT(centre[0] + centre[2], 20);
  // Marks land where they are in the full image, scaled, in their colour.
  WriteThumbnail(dir / "full.png", dir / "t" / "marked.png", 160,
                 {{{400, 300}, 0xff0000}, {{40, 440}, 0x0000ff}});
  const cv::Mat marked = cv::imread((dir / "t" / "marked.png").string());
  EXPECT_EQ(marked.at<cv::Vec3b>(75, 100), cv::Vec3b(0, 0, 255));
  EXPECT_EQ(marked.at<cv::Vec3b>(110, 10), cv::Vec3b(255, 0, 0));
  EXPECT_EQ(marked.at<cv::Vec3b>(75, 110), cv::Vec3b(0, 200, 0));  // away from the marks
  // Never scaled up.
  WriteThumbnail(dir / "full.png", dir / "t" / "same.png", 1000);
  EXPECT_EQ(cv::imread((dir / "t" / "same.png").string()).size(), cv::Size(640, 480));

  std::string m = testing::MessageOf([&] { WriteThumbnail(dir / "gone.png", dir / "x.jpg", 160); });
  EXPECT_NE(m.find("cannot read image"), std::string::npos) << m;
  EXPECT_NE(m.find("gone.png"), std::string::npos) << m;
  m = testing::MessageOf([&] { WriteThumbnail(dir / "full.png", dir / "x.gif", 160); });
  EXPECT_NE(m.find(".jpg or .png"), std::string::npos) << m;
  EXPECT_FALSE(std::filesystem::exists(dir / "x.jpg"));
}

}  // namespace
}  // namespace sdoslam
