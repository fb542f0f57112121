#include "sdoslam/place/default_vocabulary.h"

#include <string_view>

// Defined in the generated default_vocabulary_data.cc: the trained file, included byte for byte
// by the assembler (.incbin).
extern "C" const char sdoslam_default_vocabulary_begin[];
extern "C" const char sdoslam_default_vocabulary_end[];

namespace sdoslam {

std::string_view DefaultVocabularyBytes() {
  return std::string_view(
      sdoslam_default_vocabulary_begin,
      static_cast<size_t>(sdoslam_default_vocabulary_end - sdoslam_default_vocabulary_begin));
}

const Vocabulary& DefaultVocabulary() {
  // A function-local static: initialised once, thread-safe (C++11 magic statics).
  static const Vocabulary vocabulary = [] {
    const std::string_view bytes = DefaultVocabularyBytes();
    return Vocabulary::FromBytes(bytes.data(), bytes.size(), "the built-in vocabulary");
  }();
  return vocabulary;
}

}  // namespace sdoslam
