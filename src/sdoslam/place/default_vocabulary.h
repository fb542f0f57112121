#pragma once

#include <string_view>

#include "sdoslam/place/vocabulary.h"

namespace sdoslam {

// The vocabulary built into the library (target sdoslam_place_default): trained at build time
// by sdoslam_train_default_vocabulary on frames of the project's own synthetic scenes, so that
// place recognition needs no download and no file at run time (see docs/method.md,
// "Place recognition"). Loaded from the embedded bytes on first use; thread-safe.
const Vocabulary& DefaultVocabulary();

// The embedded file itself, as `sdoslam_train_default_vocabulary` wrote it.
std::string_view DefaultVocabularyBytes();

}  // namespace sdoslam
