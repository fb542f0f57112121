#include "sdoslam/core/config.h"

#include <algorithm>
#include <map>

#include "sdoslam/core/yaml_file.h"

namespace sdoslam {
namespace {

// yaml-cpp keeps every entry of a mapping but a lookup finds only the first, so a setting given
// twice silently keeps its first value. Walk the tree and refuse it, naming both lines.
void RejectDuplicateKeys(const YAML::Node& node, const std::string& origin,
                         const std::string& prefix) {
  if (node.IsSequence()) {
    for (const YAML::Node& item : node) RejectDuplicateKeys(item, origin, prefix);
    return;
  }
  if (!node.IsMap()) return;
  std::map<std::string, int> first_line;
  for (const auto& entry : node) {
    const std::string key = entry.first.IsScalar() ? entry.first.Scalar() : "(complex key)";
    const int line = entry.first.Mark().line + 1;
    const auto [it, inserted] = first_line.emplace(key, line);
    if (!inserted) {
      throw Error(origin + ":" + std::to_string(line) + ": " + prefix + key +
                  " is given twice (first on line " + std::to_string(it->second) + ")");
    }
    RejectDuplicateKeys(entry.second, origin, prefix + key + ".");
  }
}

YAML::Node CheckRoot(YAML::Node root, const std::string& origin) {
  if (root.IsNull()) root = YAML::Node(YAML::NodeType::Map);  // an empty file is allowed
  if (!root.IsMap()) throw Error(origin + ": expected a mapping of settings at the top level");
  RejectDuplicateKeys(root, origin, "");
  return root;
}

}  // namespace

ConfigMap ConfigMap::LoadFile(const std::filesystem::path& path) {
  if (!std::filesystem::exists(path)) throw Error("config file not found: " + path.string());
  return ConfigMap(CheckRoot(LoadYamlFile(path), path.string()), path.string(), "");
}

ConfigMap ConfigMap::LoadString(const std::string& text, const std::string& origin) {
  return ConfigMap(CheckRoot(ParseYaml(text, origin), origin), origin, "");
}

ConfigMap::ConfigMap(YAML::Node node, std::string origin, std::string prefix)
    : node_(std::move(node)), origin_(std::move(origin)), prefix_(std::move(prefix)) {}

bool ConfigMap::Has(const std::string& key) const {
  const YAML::Node& node = node_;
  return static_cast<bool>(node[key]);
}

YAML::Node ConfigMap::Child(const std::string& key) {
  used_.insert(key);
  const YAML::Node& node = node_;  // const access: a missing key must not be inserted
  return node[key];
}

void ConfigMap::ReadList(const std::string& key, std::vector<std::string>* values) {
  const YAML::Node child = Child(key);
  if (!child) return;
  if (!child.IsSequence()) throw Error(Where(child) + Path(key) + ": expected a list [a, b, ...]");
  values->clear();
  for (const YAML::Node& item : child) {
    if (!item.IsScalar())
      throw Error(Where(item) + Path(key) + ": list items must be single values");
    values->push_back(item.Scalar());
  }
}

std::optional<ConfigMap> ConfigMap::Section(const std::string& key) {
  const YAML::Node child = Child(key);
  if (!child) return std::nullopt;
  if (!child.IsMap()) throw Error(Where(child) + Path(key) + ": expected a mapping of settings");
  return ConfigMap(child, origin_, Path(key) + ".");
}

void ConfigMap::RejectUnknownKeys() const {
  for (const auto& entry : node_) {
    // A key that is itself a list or a map (YAML's `? [a, b]: ...`) names no setting; say so
    // instead of letting yaml-cpp's conversion exception escape as an internal error.
    if (!entry.first.IsScalar())
      throw Error(Where(entry.first) + "a key must be a plain name, not a list or map");
    const std::string key = entry.first.Scalar();
    if (!used_.count(key)) {
      std::string known;
      for (const auto& k : used_) known += (known.empty() ? "" : ", ") + k;
      throw Error(Where(entry.first) + "unknown key '" + Path(key) + "'" +
                  (known.empty() ? "" : " (known here: " + known + ")"));
    }
  }
}

std::string ConfigMap::Where(const YAML::Node& node) const {
  const YAML::Mark mark = node.Mark();
  if (mark.is_null()) return origin_ + ": ";
  return origin_ + ":" + std::to_string(mark.line + 1) + ": ";
}

}  // namespace sdoslam
