#pragma once

#include <CLI/CLI.hpp>

namespace sdoslam {

// `sdoslam eval-objects`: each ground-truth body's ids, coverage and motion error in a run's
// objects.csv (--save-objects).
void AddEvalObjectsCommand(CLI::App& app);

}  // namespace sdoslam
