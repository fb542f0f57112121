#include "sdoslam/core/config.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <chrono>

#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

using testing::MessageOf;

TEST(ConfigMap, ReadsValuesAndKeepsDefaultsForAbsentKeys) {
  ConfigMap root = ConfigMap::LoadString("a: 3\nsection:\n  b: 2.5\n  name: hi\n", "inline");
  int a = 0, missing = 42;
  root.Read("a", &a);
  root.Read("missing", &missing);
  auto section = root.Section("section");
  ASSERT_TRUE(section.has_value());
  double b = 0;
  std::string name;
  section->Read("b", &b);
  section->Read("name", &name);
  EXPECT_EQ(a, 3);
  EXPECT_EQ(missing, 42);
  EXPECT_DOUBLE_EQ(b, 2.5);
  EXPECT_EQ(name, "hi");
  EXPECT_NO_THROW(section->RejectUnknownKeys());
  EXPECT_NO_THROW(root.RejectUnknownKeys());
  EXPECT_FALSE(root.Section("absent").has_value());
}

TEST(ConfigMap, ReadsListsAndRejectsScalarsWhereAListIsExpected) {
  ConfigMap root = ConfigMap::LoadString("a: [person, dog]\nb:\n  - cat\nc: 1\n", "l.yaml");
  std::vector<std::string> a, b, c = {"kept"}, absent = {"default"};
  root.ReadList("a", &a);
  root.ReadList("b", &b);
  root.ReadList("absent", &absent);
  EXPECT_EQ(a, (std::vector<std::string>{"person", "dog"}));
  EXPECT_EQ(b, (std::vector<std::string>{"cat"}));
  EXPECT_EQ(absent, (std::vector<std::string>{"default"}));
  EXPECT_EQ(MessageOf([&] { root.ReadList("c", &c); }), "l.yaml:4: c: expected a list [a, b, ...]");
}

TEST(ConfigMap, UnknownKeyIsNamedWithItsPathAndLine) {
  ConfigMap root = ConfigMap::LoadString("camera:\n  fx: 500\n  fxx: 1\n", "cam.yaml");
  auto camera = root.Section("camera");
  double fx = 0;
  camera->Read("fx", &fx);
  EXPECT_EQ(MessageOf([&] { camera->RejectUnknownKeys(); }),
            "cam.yaml:3: unknown key 'camera.fxx' (known here: fx)");
}

TEST(ConfigMap, AKeyThatIsAListOrMapIsNamedNotAnInternalError) {
  // Found by fuzz/config_fuzz: YAML's explicit key `? ...` may be a list; yaml-cpp's string
  // conversion of it threw its own exception past every handler.
  ConfigMap root = ConfigMap::LoadString("mode: sdo\n? [a, b]\n: 1\n", "k.yaml");
  std::string mode;
  root.Read("mode", &mode);
  EXPECT_EQ(MessageOf([&] { root.RejectUnknownKeys(); }),
            "k.yaml:2: a key must be a plain name, not a list or map");
}

TEST(ConfigMap, AKeyGivenTwiceIsAnErrorNamingBothLines) {
  // yaml-cpp alone keeps the first value and drops the second without a word.
  EXPECT_EQ(MessageOf([] {
              ConfigMap::LoadString("camera:\n  fx: 500\n  fy: 1\n  fx: 600\n", "c.yaml");
            }),
            "c.yaml:4: camera.fx is given twice (first on line 2)");
  EXPECT_EQ(MessageOf([] { ConfigMap::LoadString("mode: sdo\nmode: oracle\n", "c.yaml"); }),
            "c.yaml:2: mode is given twice (first on line 1)");
  // The same key in two sections is fine.
  EXPECT_EQ(MessageOf([] { ConfigMap::LoadString("a:\n  x: 1\nb:\n  x: 2\n", "c.yaml"); }),
            "(no error)");
}

TEST(ConfigMap, WrongTypesAndBadYamlAreReportedWithLine) {
  ConfigMap root = ConfigMap::LoadString("n: 1\nwidth: wide\nlist: [1, 2]\n", "c.yaml");
  int width = 0;
  EXPECT_EQ(MessageOf([&] { root.Read("width", &width); }),
            "c.yaml:2: width: cannot read 'wide' as an integer");
  double value = 0;
  EXPECT_EQ(MessageOf([&] { root.Read("list", &value); }),
            "c.yaml:3: list: expected a single value");
  EXPECT_EQ(MessageOf([&] { root.Section("n"); }), "c.yaml:1: n: expected a mapping of settings");
  EXPECT_NE(
      MessageOf([] { ConfigMap::LoadString("a: [1, 2\nb: 3\n", "bad.yaml"); }).find("bad.yaml:"),
      std::string::npos);
  EXPECT_NE(MessageOf([] { ConfigMap::LoadString("- 1\n- 2\n", "seq.yaml"); }).find("mapping"),
            std::string::npos);
}

TEST(ConfigMap, MissingFileIsNamed) {
  EXPECT_EQ(MessageOf([] { ConfigMap::LoadFile("/no/such/config.yaml"); }),
            "config file not found: /no/such/config.yaml");
}

// Ten levels of ten aliases (10^10 nodes expanded, 300 bytes) ran for minutes in the duplicate-
// and unknown-key checks; smaller ones took 19-48 s to fail. Now each fails at once, naming the
// file, whether read from a file (a --config, a camera.yaml) or from text.
TEST(ConfigMap, AnAliasBombFailsAtOnceNamingTheFile) {
  testing::TempDir dir;
  for (int levels : {7, 8, 10}) {
    testing::WriteText(dir / "bomb.yaml", testing::YamlAliasBomb(levels));
    for (const bool from_file : {true, false}) {
      const auto start = std::chrono::steady_clock::now();
      const std::string message = MessageOf([&] {
        if (from_file) {
          ConfigMap::LoadFile(dir / "bomb.yaml");
        } else {
          ConfigMap::LoadString(testing::YamlAliasBomb(levels), (dir / "bomb.yaml").string());
        }
      });
      EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
                2.0)
          << levels;
      EXPECT_EQ(message.find((dir / "bomb.yaml").string() + ": more than 100000 YAML nodes"), 0u)
          << message;
    }
  }
}

// A config that is a FIFO blocked the run until something wrote to it; a folder was "not found".
TEST(ConfigMap, AConfigThatIsNoRegularFileIsRefusedAtOnce) {
  testing::TempDir dir;
  ASSERT_EQ(mkfifo((dir / "fifo.yaml").c_str(), 0600), 0);
  EXPECT_EQ(MessageOf([&] { ConfigMap::LoadFile(dir / "fifo.yaml"); }),
            (dir / "fifo.yaml").string() + ": not a regular file");
  EXPECT_EQ(MessageOf([&] { ConfigMap::LoadFile(dir.path()); }),
            dir.path().string() + ": not a regular file");
}

}  // namespace
}  // namespace sdoslam
