// docs/configuration.md against the options: every setting of the SLAM sections, dynamic: and objects:
// is in its YAML blocks with its default, and every key there is a setting. A setting added,
// renamed or given a new default without the reference fails here.

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>

#include "sdoslam/dynamic/front_end.h"
#include "sdoslam/objects/object_tracker.h"
#include "sdoslam/slam/system.h"
#include "sdoslam/testing/options_test_util.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

// What the reference shows for a key: its value as text, or that it shows part of a list only
// ("[person, dog, car, ...]") or a section placeholder ("consistency: {...}").
struct Shown {
  std::string text;
  bool partial = false;
};

// The scalars (and lists, their items joined by ';' as FieldValues writes them) under `node`,
// by dotted path.
void Flatten(const YAML::Node& node, const std::string& path, std::map<std::string, Shown>* out) {
  if (node.IsMap()) {
    for (const auto& entry : node) {
      const std::string key = entry.first.as<std::string>();
      if (key == "...") continue;  // a placeholder for a section shown elsewhere
      Flatten(entry.second, path.empty() ? key : path + "." + key, out);
    }
  } else if (node.IsSequence()) {
    Shown shown;
    for (const auto& item : node) {
      const std::string text = item.as<std::string>();
      if (text == "...") shown.partial = true;
      shown.text += text + ";";
    }
    (*out)[path] = shown;
  } else {
    (*out)[path] = {node.IsNull() ? "" : node.as<std::string>()};
  }
}

// The keys the reference's ```yaml blocks show.
std::map<std::string, Shown> DocumentedKeys() {
  std::ifstream in(testing::SourceDir() / "docs" / "configuration.md");
  std::stringstream text;
  text << in.rdbuf();
  const std::string doc = text.str();
  std::map<std::string, Shown> keys;
  const std::regex block("```yaml\\n([\\s\\S]*?)```");
  for (auto it = std::sregex_iterator(doc.begin(), doc.end(), block); it != std::sregex_iterator();
       ++it) {
    Flatten(YAML::Load((*it)[1].str()), "", &keys);
  }
  return keys;
}

// Whether the reference's `shown` is the setting's `value` (FieldValues' text: doubles with 17
// digits, so numbers are compared as numbers).
bool SameValue(const std::string& shown, const std::string& value) {
  if (shown == value) return true;
  try {
    size_t used_shown = 0, used_value = 0;
    const double a = std::stod(shown, &used_shown), b = std::stod(value, &used_value);
    return used_shown == shown.size() && used_value == value.size() && a == b;
  } catch (const std::exception&) {
    return false;
  }
}

TEST(ConfigurationReference, ShowsEverySettingWithItsDefaultAndNothingElse) {
  const std::map<std::string, Shown> documented = DocumentedKeys();
  ASSERT_GT(documented.size(), 100u) << "docs/configuration.md: its yaml blocks did not read";
  std::map<std::string, std::string> settings = testing::FieldValues(SlamOptions());
  for (const auto& [path, value] : testing::FieldValues(FrontEndOptions()))
    settings["dynamic." + path] = value;
  for (const auto& [path, value] : testing::FieldValues(ObjectTrackerOptions()))
    settings["objects." + path] = value;
  for (const auto& [path, value] : settings) {
    SCOPED_TRACE(path);
    const auto it = documented.find(path);
    if (it == documented.end()) {
      ADD_FAILURE() << "not in docs/configuration.md (default " << value << ")";
      continue;
    }
    if (!it->second.partial) {
      EXPECT_TRUE(SameValue(it->second.text, value))
          << "docs/configuration.md shows " << it->second.text << ", the default is " << value;
    }
  }
  // camera: shows an example camera, not defaults; its keys are CameraOptions', read elsewhere.
  for (const auto& [path, shown] : documented) {
    if (path.rfind("camera.", 0) == 0) continue;
    EXPECT_TRUE(settings.count(path))
        << "docs/configuration.md shows " << path << ", which is no setting";
  }
}

// The comparison itself: a number shown with fewer digits is the same number, a different one
// is not, and text is compared as text.
TEST(ConfigurationReference, ComparesNumbersAsNumbers) {
  EXPECT_TRUE(SameValue("0.6", "0.59999999999999998"));
  EXPECT_TRUE(SameValue("40.0", "40"));
  EXPECT_FALSE(SameValue("0.5", "0.59999999999999998"));
  EXPECT_FALSE(SameValue("1e", "1"));
  EXPECT_TRUE(SameValue("hog", "hog"));
  EXPECT_FALSE(SameValue("hog", "none"));
}

}  // namespace
}  // namespace sdoslam
