#pragma once

#include <CLI/CLI.hpp>

namespace sdoslam {

// `sdoslam eval-masks`: per-pixel and per-feature precision/recall/IoU of the dynamic masks a
// run saved (--save-masks) against a synthetic sequence's ground truth.
void AddEvalMasksCommand(CLI::App& app);

}  // namespace sdoslam
