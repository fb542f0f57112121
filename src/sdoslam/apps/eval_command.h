#pragma once

#include <CLI/CLI.hpp>

namespace sdoslam {

// `sdoslam eval`: ATE and RTE of one or more estimated trajectories against ground truth.
void AddEvalCommand(CLI::App& app);

}  // namespace sdoslam
