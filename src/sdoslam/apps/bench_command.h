#pragma once

#include <CLI/CLI.hpp>

namespace sdoslam {

// `sdoslam bench`: timing of whole SLAM runs, repeated, reported as medians.
void AddBenchCommand(CLI::App& app);

}  // namespace sdoslam
