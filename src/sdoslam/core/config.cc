#include "sdoslam/core/config.h"

#include <fstream>
#include <sstream>

namespace sdoslam {
namespace {

YAML::Node ParseRoot(const std::string& text, const std::string& origin) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    throw Error(origin + ":" + std::to_string(e.mark.line + 1) + ": invalid YAML: " + e.msg);
  }
  if (root.IsNull()) root = YAML::Node(YAML::NodeType::Map);  // an empty file is allowed
  if (!root.IsMap()) throw Error(origin + ": expected a mapping of settings at the top level");
  return root;
}

}  // namespace

ConfigMap ConfigMap::LoadFile(const std::filesystem::path& path) {
  if (!std::filesystem::is_regular_file(path))
    throw Error("config file not found: " + path.string());
  std::ifstream in(path);
  if (!in) throw Error("cannot read config file " + path.string());
  std::stringstream text;
  text << in.rdbuf();
  return ConfigMap(ParseRoot(text.str(), path.string()), path.string(), "");
}

ConfigMap ConfigMap::LoadString(const std::string& text, const std::string& origin) {
  return ConfigMap(ParseRoot(text, origin), origin, "");
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
    const std::string key = entry.first.as<std::string>();
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
