#pragma once

#include <CLI/CLI.hpp>

namespace sdoslam {

// `sdoslam convert`: a sequence of any supported layout written out in the TUM layout.
void AddConvertCommand(CLI::App& app);

}  // namespace sdoslam
