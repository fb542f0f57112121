#pragma once

#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "sdoslam/core/error.h"

namespace sdoslam {

// A YAML mapping read key by key. Every key read is remembered; RejectUnknownKeys() then throws
// for the first key nobody asked for, so that a misspelt setting is an error instead of a silent
// fall-back to its default (ORB-SLAM2's scar). Messages name file, line and the dotted key.
class ConfigMap {
 public:
  // Parses `path`; its root must be a mapping. Throws Error naming the file (and line).
  static ConfigMap LoadFile(const std::filesystem::path& path);
  // Parses YAML text (for tests and command-line overrides); `origin` names it in messages.
  static ConfigMap LoadString(const std::string& text, const std::string& origin);

  ConfigMap(YAML::Node node, std::string origin, std::string prefix);

  bool Has(const std::string& key) const;

  // Reads an optional scalar: leaves *value untouched when the key is absent.
  template <typename T>
  void Read(const std::string& key, T* value) {
    const YAML::Node child = Child(key);
    if (!child) return;
    if (!child.IsScalar()) throw Error(Where(child) + Path(key) + ": expected a single value");
    try {
      *value = child.as<T>();
    } catch (const YAML::Exception&) {
      throw Error(Where(child) + Path(key) + ": cannot read '" + child.Scalar() + "' as " +
                  TypeName<T>());
    }
  }

  // Reads an optional list of text values ([a, b] or a block sequence).
  void ReadList(const std::string& key, std::vector<std::string>* values);

  // Nested mapping `key`, or nullopt when absent. Throws when present but not a mapping.
  std::optional<ConfigMap> Section(const std::string& key);

  void RejectUnknownKeys() const;

  const std::string& origin() const { return origin_; }

 private:
  YAML::Node Child(const std::string& key);
  std::string Path(const std::string& key) const { return prefix_ + key; }
  std::string Where(const YAML::Node& node) const;

  template <typename T>
  static const char* TypeName() {
    if constexpr (std::is_same_v<T, bool>) return "true/false";
    if constexpr (std::is_integral_v<T>) return "an integer";
    if constexpr (std::is_floating_point_v<T>) return "a number";
    return "text";
  }

  YAML::Node node_;
  std::string origin_;
  std::string prefix_;  // "camera." for keys below camera:
  std::set<std::string> used_;
};

}  // namespace sdoslam
