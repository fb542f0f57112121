#pragma once
// Shared by the libFuzzer targets: the readers under test take paths, so each input is written
// to a file in a scratch folder of this process first.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <utility>

namespace sdoslam::fuzz {

// A folder of this process, removed at exit.
inline const std::filesystem::path& ScratchDir() {
  struct Scratch {
    Scratch()
        : path(std::filesystem::temp_directory_path() /
               ("sdoslam_fuzz_" + std::to_string(::getpid()))) {
      std::filesystem::create_directories(path);
    }
    ~Scratch() {
      std::error_code ec;
      std::filesystem::remove_all(path, ec);
    }
    std::filesystem::path path;
  };
  static const Scratch scratch;
  return scratch.path;
}

inline std::filesystem::path WriteInput(const std::string& name, std::string_view data) {
  const auto path = ScratchDir() / name;
  std::filesystem::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary | std::ios::trunc).write(data.data(), data.size());
  return path;
}

inline std::string_view AsText(const uint8_t* data, size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

// Splits an input in two at the first "\n----\n" (for readers of two files at once).
inline std::pair<std::string_view, std::string_view> SplitInTwo(std::string_view text) {
  const size_t at = text.find("\n----\n");
  if (at == std::string_view::npos) return {text, {}};
  return {text.substr(0, at + 1), text.substr(at + 6)};
}

}  // namespace sdoslam::fuzz
