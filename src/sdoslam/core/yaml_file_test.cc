#include "sdoslam/core/yaml_file.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <chrono>
#include <functional>
#include <string>

#include "sdoslam/core/error.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

double SecondsFor(const std::function<void()>& f) {
  const auto start = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

TEST(YamlFile, ParsesAnOrdinaryDocument) {
  const YAML::Node root = ParseYaml("a: 1\nb: [2, 3]\nc: {d: x}\n", "t.yaml");
  EXPECT_EQ(root["a"].as<int>(), 1);
  EXPECT_EQ(root["b"].size(), 2u);
  // Aliases are allowed as such: a few copies are far within the bound.
  EXPECT_TRUE(ParseYaml(testing::YamlAliasBomb(3), "t.yaml").IsMap());  // 10^3 nodes
}

TEST(YamlFile, SyntaxErrorsNameOriginAndLine) {
  EXPECT_NE(testing::MessageOf([] { ParseYaml("a: 1\nb: [2\n", "t.yaml"); }).find("t.yaml:"),
            std::string::npos);
}

TEST(YamlFile, AnAliasBombFailsAtOnceNamingTheFile) {
  for (int levels : {6, 10}) {  // 10^6 nodes and 10^10
    std::string message;
    const double seconds = SecondsFor([&] {
      message = testing::MessageOf([&] { ParseYaml(testing::YamlAliasBomb(levels), "bomb.yaml"); });
    });
    EXPECT_LT(seconds, 2.0) << levels;
    EXPECT_NE(message.find("bomb.yaml: more than 100000 YAML nodes"), std::string::npos) << message;
  }
}

TEST(YamlFile, FilesAreBoundedInSizeAndMustBeRegular) {
  testing::TempDir dir;
  testing::WriteText(dir / "big.yaml", "a: '" + std::string(kMaxYamlBytes, 'x') + "'\n");
  const std::string big = testing::MessageOf([&] { LoadYamlFile(dir / "big.yaml"); });
  EXPECT_NE(big.find((dir / "big.yaml").string() + ": "), std::string::npos) << big;
  EXPECT_NE(big.find("more than the 1.0 MiB"), std::string::npos) << big;
  ASSERT_EQ(mkfifo((dir / "fifo.yaml").c_str(), 0600), 0);
  EXPECT_EQ(testing::MessageOf([&] { LoadYamlFile(dir / "fifo.yaml"); }),
            (dir / "fifo.yaml").string() + ": not a regular file");
  EXPECT_EQ(testing::MessageOf([&] { LoadYamlFile(dir / "absent.yaml"); }),
            (dir / "absent.yaml").string() + ": not found");
}

}  // namespace
}  // namespace sdoslam
