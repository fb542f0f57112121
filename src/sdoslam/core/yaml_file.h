#pragma once

#include <yaml-cpp/yaml.h>

#include <cstdint>
#include <filesystem>
#include <string>

namespace sdoslam {

// Every YAML document the program reads (configs, camera.yaml, an OMD segment's kalibr.yaml and
// vicon.yaml) is parsed here, within two bounds. yaml-cpp shares the node of an &anchor among its
// *aliases, so parsing is cheap, but anything that walks the tree (the duplicate- and
// unknown-key checks) meets every alias expanded: ten levels of ten aliases each are 10^10
// nodes, and such a 300-byte config ran for minutes. A settings file has a few hundred nodes.
inline constexpr uint64_t kMaxYamlBytes = uint64_t{1} << 20;
inline constexpr size_t kMaxYamlNodes = 100'000;

// Parses YAML text; `origin` names it in messages. Throws Error("<origin>:<line>: invalid YAML:
// ...") for a syntax error and Error naming `origin` when the document has more than
// kMaxYamlNodes nodes with its aliases expanded.
YAML::Node ParseYaml(const std::string& text, const std::string& origin);

// Reads a regular file of at most kMaxYamlBytes (regular_file.h; a missing one is
// "<path>: not found") and parses it with ParseYaml.
YAML::Node LoadYamlFile(const std::filesystem::path& path);

}  // namespace sdoslam
