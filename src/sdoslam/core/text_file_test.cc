#include "sdoslam/core/text_file.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include "sdoslam/core/error.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

TEST(TextFile, SkipsCommentsAndBlankLinesAndReportsRealLineNumbers) {
  testing::TempDir dir;
  testing::WriteText(dir / "a.txt", "# header\n\n1 a\r\n  # indented comment\n2\tb  c\n");
  std::vector<std::pair<int, std::vector<std::string>>> seen;
  ForEachDataLine(dir / "a.txt", [&](int line, const std::vector<std::string>& tokens) {
    seen.emplace_back(line, tokens);
  });
  ASSERT_EQ(seen.size(), 2u);
  EXPECT_EQ(seen[0].first, 3);
  EXPECT_EQ(seen[0].second, (std::vector<std::string>{"1", "a"}));
  EXPECT_EQ(seen[1].first, 5);
  EXPECT_EQ(seen[1].second, (std::vector<std::string>{"2", "b", "c"}));
}

TEST(TextFile, MissingFileNamesThePath) {
  try {
    ForEachDataLine("/nonexistent/list.txt", [](int, const auto&) {});
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/list.txt"), std::string::npos);
  }
}

TEST(TextFile, ParseDoubleRejectsGarbageAndNonFinite) {
  EXPECT_DOUBLE_EQ(ParseDouble("1311868164.363181", "f", 1, "timestamp"), 1311868164.363181);
  EXPECT_THROW(ParseDouble("12abc", "f", 1, "x"), Error);
  EXPECT_THROW(ParseDouble("", "f", 1, "x"), Error);
  EXPECT_THROW(ParseDouble("nan", "f", 1, "x"), Error);
  EXPECT_THROW(ParseDouble("inf", "f", 1, "x"), Error);
  try {
    ParseDouble("oops", "traj.txt", 7, "tx");
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "traj.txt:7: tx 'oops' is not a number");
  }
}

TEST(TextFile, ParseTimestampRefusesWhatIsNoTimeInSeconds) {
  EXPECT_DOUBLE_EQ(ParseTimestamp("1311868164.363181", "f", 1, "timestamp"), 1311868164.363181);
  EXPECT_DOUBLE_EQ(ParseTimestamp("0", "f", 1, "timestamp"), 0.0);  // synthetic sequences
  EXPECT_EQ(testing::MessageOf([] { ParseTimestamp("1e308", "rgb.txt", 9, "timestamp"); }),
            "rgb.txt:9: timestamp 1e308 is not a time in seconds (beyond +-1e+10 s, the year "
            "2286; nanoseconds?)");
  EXPECT_THROW(ParseTimestamp("1311868164363181000", "f", 1, "timestamp"), Error);  // ns
  EXPECT_THROW(ParseTimestamp("-2e10", "f", 1, "timestamp"), Error);
  EXPECT_THROW(ParseTimestamp("inf", "f", 1, "timestamp"), Error);
}

// A list that is a FIFO blocked the reader; one that is a folder read as empty.
TEST(TextFile, AListThatIsNoRegularFileIsRefused) {
  testing::TempDir dir;
  ASSERT_EQ(mkfifo((dir / "rgb.txt").c_str(), 0600), 0);
  EXPECT_EQ(testing::MessageOf([&] { ForEachDataLine(dir / "rgb.txt", [](int, const auto&) {}); }),
            (dir / "rgb.txt").string() + ": not a regular file");
  EXPECT_EQ(testing::MessageOf([&] { ForEachDataLine(dir.path(), [](int, const auto&) {}); }),
            dir.path().string() + ": not a regular file");
}

}  // namespace
}  // namespace sdoslam
