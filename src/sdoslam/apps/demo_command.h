#pragma once

#include <CLI/CLI.hpp>

namespace sdoslam {

// `sdoslam demo`: the README's first command runs this. It needs no dataset and no model.
void AddDemoCommand(CLI::App& app);

}  // namespace sdoslam
