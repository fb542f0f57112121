#include "sdoslam/core/yaml_file.h"

#include <fmt/format.h>

#include <vector>

#include "sdoslam/core/error.h"
#include "sdoslam/core/regular_file.h"

namespace sdoslam {
namespace {

// Counts the nodes of `root` as a walk meets them (an alias's target once per alias), and stops
// past kMaxYamlNodes: the walk costs at most that many steps, however large the expansion.
bool WithinNodeBudget(const YAML::Node& root) {
  std::vector<YAML::Node> pending{root};
  size_t count = 1;
  auto visit = [&](const YAML::Node& child) {
    pending.push_back(child);
    return ++count <= kMaxYamlNodes;
  };
  while (!pending.empty()) {
    const YAML::Node node = pending.back();
    pending.pop_back();
    if (node.IsSequence()) {
      for (const YAML::Node& item : node)
        if (!visit(item)) return false;
    } else if (node.IsMap()) {
      for (const auto& entry : node)
        if (!visit(entry.first) || !visit(entry.second)) return false;
    }
  }
  return true;
}

}  // namespace

YAML::Node ParseYaml(const std::string& text, const std::string& origin) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {  // a ParserException, or too deep a nesting
    throw Error(origin + ":" + std::to_string(e.mark.line + 1) + ": invalid YAML: " + e.msg);
  }
  if (!WithinNodeBudget(root)) {
    throw Error(fmt::format(
        "{}: more than {} YAML nodes, counting each *alias as a copy of its &anchor (a settings "
        "file has a few hundred); refused before it is read",
        origin, kMaxYamlNodes));
  }
  return root;
}

YAML::Node LoadYamlFile(const std::filesystem::path& path) {
  return ParseYaml(ReadRegularFile(path, kMaxYamlBytes), path.string());
}

}  // namespace sdoslam
