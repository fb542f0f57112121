#pragma once

#include <CLI/CLI.hpp>

namespace sdoslam {

// `sdoslam run`: SLAM on an RGB-D sequence in the TUM layout.
void AddRunCommand(CLI::App& app);

}  // namespace sdoslam
