#pragma once

#include <CLI/CLI.hpp>

namespace sdoslam {

// `sdoslam vocab build`: trains a place-recognition vocabulary on a user's images;
// `sdoslam vocab info`: describes a vocabulary file or the built-in one.
void AddVocabCommand(CLI::App& app);

}  // namespace sdoslam
