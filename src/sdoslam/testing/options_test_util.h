#pragma once

// Tests of the options' config keys: every setting is reached through its VisitFields (core/
// config.h), so these helpers change and compare options setting by setting without a list of
// their own.

#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>
#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "sdoslam/core/config.h"
#include "sdoslam/core/error.h"

namespace sdoslam::testing {

// The YAML a section writer (WriteSlamOptions, WriteFrontEndOptions) emits into a top-level map.
template <class Options, class Write>
std::string WrittenYaml(const Options& options, Write&& write) {
  YAML::Emitter out;
  out << YAML::BeginMap;
  write(options, &out);
  out << YAML::EndMap;
  return out.c_str();
}

// The message of the Error that a config reader (ReadSlamOptions, ReadFrontEndOptions) throws on
// `yaml`, loaded as c.yaml; "" when it reads.
template <class Read>
std::string ReadErrorOf(const std::string& yaml, Read&& read) {
  try {
    ConfigMap root = ConfigMap::LoadString(yaml, "c.yaml");
    read(root);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

// Every setting's value as text (doubles with all 17 digits), by its dotted path.
template <class Options>
std::map<std::string, std::string> FieldValues(const Options& options) {
  std::map<std::string, std::string> values;
  VisitPaths(options, "", [&](const std::string& path, const auto& value) {
    using V = std::remove_cvref_t<decltype(value)>;
    std::ostringstream text;
    text.precision(17);
    if constexpr (std::is_same_v<V, std::vector<std::string>>) {
      for (const std::string& item : value) text << item << ";";
    } else if constexpr (std::is_same_v<V, std::filesystem::path>) {
      text << value.string();
    } else if constexpr (std::is_same_v<V, bool>) {
      text << (value ? "true" : "false");
    } else if constexpr (std::is_integral_v<V>) {
      text << +value;
    } else {
      text << value;
    }
    values[path] = text.str();
  });
  return values;
}

// Gives every setting a value of its own that is not its default: the n-th setting's integer
// grows by n + 1, its number becomes 1.5·x + 0.25 + n, a flag flips, text and paths become
// "x_<path>", a list two items named after the path. (Not valid options: for the keys only.)
template <class Options>
void ChangeEveryField(Options* options) {
  int n = 0;
  VisitPaths(*options, "", [&](const std::string& path, auto& value) {
    using V = std::remove_cvref_t<decltype(value)>;
    if constexpr (std::is_same_v<V, std::vector<std::string>>) {
      value = {"a_" + path, "b_" + path};
    } else if constexpr (std::is_same_v<V, std::filesystem::path> ||
                         std::is_same_v<V, std::string>) {
      value = "x_" + path;
    } else if constexpr (std::is_same_v<V, bool>) {
      value = !value;
    } else if constexpr (std::is_integral_v<V>) {
      value = static_cast<V>(value + n + 1);
    } else {
      static_assert(std::is_floating_point_v<V>, "a setting of a type these tests do not know");
      value = value * 1.5 + 0.25 + n;
    }
    ++n;
  });
}

// A value of the setting at `path` that still passes the options' checks where its default does
// (an integer + 2, a number halved or 0 made 0.25, a flag flipped, text "x"), written as YAML, and
// the text the setting then has in FieldValues. False when `path` is no setting.
template <class Options>
bool NearbyValue(const std::string& path, std::string* yaml, std::string* expected) {
  Options options;
  bool found = false;
  VisitPaths(options, "", [&](const std::string& p, auto& value) {
    if (p != path) return;
    found = true;
    using V = std::remove_cvref_t<decltype(value)>;
    if constexpr (std::is_same_v<V, std::vector<std::string>>) {
      value = {"x", "y"};
      *yaml = "[x, y]";
    } else if constexpr (std::is_same_v<V, std::filesystem::path> ||
                         std::is_same_v<V, std::string>) {
      value = "x";
      *yaml = "x";
    } else if constexpr (std::is_same_v<V, bool>) {
      value = !value;
      *yaml = value ? "true" : "false";
    } else if constexpr (std::is_integral_v<V>) {
      value = static_cast<V>(value + 2);
      *yaml = std::to_string(+value);
    } else {
      value = value == 0 ? 0.25 : value * 0.5;
      std::ostringstream text;
      text.precision(17);
      text << value;
      *yaml = text.str();
    }
  });
  if (found) *expected = FieldValues(options).at(path);
  return found;
}

// Reads `yaml` with `read` (ReadSlamOptions or ReadFrontEndOptions) and checks nothing is left
// unread; the settings' values by path.
template <class Read>
std::map<std::string, std::string> ReadValues(const std::string& yaml, const std::string& origin,
                                              Read read) {
  ConfigMap root = ConfigMap::LoadString(yaml, origin);
  const auto values = FieldValues(read(root));
  root.RejectUnknownKeys();
  return values;
}

// "a.b.c: v" as nested YAML blocks.
inline std::string NestedYaml(const std::string& path, const std::string& value) {
  std::string yaml, indent;
  size_t start = 0;
  for (size_t dot; (dot = path.find('.', start)) != std::string::npos; start = dot + 1) {
    yaml += indent + path.substr(start, dot - start) + ":\n";
    indent += "  ";
  }
  return yaml + indent + path.substr(start) + ": " + value + "\n";
}

// spdlog's messages while it lives, as text.
class CapturedLog {
 public:
  CapturedLog() : previous_(spdlog::default_logger()) {
    auto sink = std::make_shared<spdlog::sinks::ostream_sink_mt>(text_);
    spdlog::set_default_logger(std::make_shared<spdlog::logger>("captured", sink));
  }
  ~CapturedLog() { spdlog::set_default_logger(previous_); }
  CapturedLog(const CapturedLog&) = delete;
  CapturedLog& operator=(const CapturedLog&) = delete;
  std::string text() const { return text_.str(); }
  // Occurrences of `needle`.
  int Count(const std::string& needle) const {
    const std::string all = text();
    int count = 0;
    for (size_t at = all.find(needle); at != std::string::npos; at = all.find(needle, at + 1))
      ++count;
    return count;
  }

 private:
  std::ostringstream text_;
  std::shared_ptr<spdlog::logger> previous_;
};

}  // namespace sdoslam::testing
