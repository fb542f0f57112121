#pragma once

#include <CLI/CLI.hpp>

namespace sdoslam {

// `sdoslam synth`: synthetic dynamic RGB-D sequences with full ground truth.
void AddSynthCommand(CLI::App& app);

}  // namespace sdoslam
