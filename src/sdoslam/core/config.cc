#include "sdoslam/core/config.h"

#include <spdlog/spdlog.h>

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

namespace {

// A value below the mapping: its dotted path (below the mapping), its parent mapping and key.
struct Leaf {
  std::string path;
  YAML::Node parent;
  std::string key;
};

void CollectLeaves(const YAML::Node& map, const std::string& prefix, std::vector<Leaf>* leaves) {
  for (const auto& entry : map) {
    if (!entry.first.IsScalar()) continue;  // RejectUnknownKeys names it
    const std::string path = prefix + entry.first.Scalar();
    if (entry.second.IsMap() && entry.second.size() > 0) {
      CollectLeaves(entry.second, path + ".", leaves);
    } else {
      leaves->push_back({path, map, entry.first.Scalar()});
    }
  }
}

std::vector<std::string> SplitPath(const std::string& path) {
  std::vector<std::string> parts;
  size_t start = 0;
  for (size_t dot; (dot = path.find('.', start)) != std::string::npos; start = dot + 1)
    parts.push_back(path.substr(start, dot - start));
  parts.push_back(path.substr(start));
  return parts;
}

}  // namespace

void ConfigMap::ApplyAliases(std::span<const ConfigAlias> aliases,
                             const std::vector<std::string>& known_keys) {
  auto known = [&](const std::string& path) {
    return std::find(known_keys.begin(), known_keys.end(), path) != known_keys.end();
  };
  // The alias of a key: its own entry, or the entry of the nearest section above it that moved.
  auto new_path_of = [&](const std::string& path) -> std::optional<std::string> {
    const ConfigAlias* best = nullptr;
    size_t best_length = 0;
    for (const ConfigAlias& alias : aliases) {
      const std::string old_path = alias.old_path;
      const bool exact = path == old_path;
      const bool below = !known(alias.new_path) && path.size() > old_path.size() &&
                         path.compare(0, old_path.size(), old_path) == 0 &&
                         path[old_path.size()] == '.';
      if ((exact || below) && old_path.size() >= best_length) {
        best = &alias;
        best_length = old_path.size();
      }
    }
    if (best == nullptr) return std::nullopt;
    return std::string(best->new_path) + path.substr(best_length);
  };
  auto line_of = [](const YAML::Node& node) {
    return node.Mark().is_null() ? std::string("?") : std::to_string(node.Mark().line + 1);
  };
  std::vector<Leaf> leaves;
  CollectLeaves(node_, "", &leaves);
  std::vector<std::string> moved;  // old paths, for the sections the moves emptied
  for (const Leaf& leaf : leaves) {
    const std::optional<std::string> new_path = new_path_of(leaf.path);
    if (!new_path) continue;
    YAML::Node parent = leaf.parent;  // a handle: changes go to the tree
    const YAML::Node value = leaf.parent[leaf.key];
    moved.push_back(leaf.path);
    if (value.IsMap()) {  // an old section written empty ({}): nothing to move
      spdlog::warn("{}:{}: config section '{}' is deprecated, its settings are below '{}'", origin_,
                   line_of(value), Path(leaf.path), Path(*new_path));
      parent.remove(leaf.key);
      continue;
    }
    if (!known(*new_path)) {
      throw Error(Where(value) + "unknown key '" + Path(leaf.path) + "' (" + Path(*new_path) +
                  " names no setting either)");
    }
    // Walk down to the new key's mapping, making the sections that are missing. (reset() moves
    // a handle; assigning to a YAML::Node would overwrite the node it refers to.)
    const std::vector<std::string> parts = SplitPath(*new_path);
    YAML::Node map(node_);
    std::string walked;
    for (size_t i = 0; i + 1 < parts.size(); ++i) {
      walked += parts[i];
      const YAML::Node& const_map = map;
      if (const YAML::Node next = const_map[parts[i]]) {
        if (!next.IsMap()) {
          throw Error(Where(next) + Path(walked) + ": expected a mapping of settings (" +
                      Path(leaf.path) + " on line " + line_of(value) + " is read as " +
                      Path(*new_path) + ")");
        }
      } else {
        map[parts[i]] = YAML::Node(YAML::NodeType::Map);
      }
      const YAML::Node next = const_map[parts[i]];
      map.reset(next);
      walked += ".";
    }
    const YAML::Node& const_map = map;
    if (const YAML::Node existing = const_map[parts.back()]) {
      throw Error(origin_ + ": " + Path(leaf.path) + " (line " + line_of(value) +
                  ") is the deprecated name of " + Path(*new_path) + " (line " + line_of(existing) +
                  "): give only " + Path(*new_path));
    }
    spdlog::warn("{}:{}: config key '{}' is deprecated, it is now '{}' (read as that; rename it)",
                 origin_, line_of(value), Path(leaf.path), Path(*new_path));
    map[parts.back()] = value;
    parent.remove(leaf.key);
  }
  // Sections the moves emptied go too: they held nothing but the moved keys.
  for (const std::string& path : moved) {
    std::vector<std::string> parts = SplitPath(path);
    while (parts.size() > 1) {
      parts.pop_back();
      YAML::Node parent(node_);
      bool found = true;
      for (size_t i = 0; i + 1 < parts.size() && found; ++i) {
        const YAML::Node& const_parent = parent;
        const YAML::Node next = const_parent[parts[i]];
        found = next && next.IsMap();
        if (found) parent.reset(next);
      }
      if (!found) break;
      const YAML::Node& const_parent = parent;
      const YAML::Node section = const_parent[parts.back()];
      if (!section || !section.IsMap() || section.size() > 0) break;
      parent.remove(parts.back());
    }
  }
}

std::string ConfigMap::Where(const YAML::Node& node) const {
  const YAML::Mark mark = node.Mark();
  if (mark.is_null()) return origin_ + ": ";
  return origin_ + ":" + std::to_string(mark.line + 1) + ": ";
}

}  // namespace sdoslam
