#pragma once

#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <stdexcept>
#include <string>
#include <system_error>

namespace sdoslam::testing {

// A fresh folder under the system temp dir, removed with everything in it on destruction.
class TempDir {
 public:
  TempDir() {
    std::string pattern = (std::filesystem::temp_directory_path() / "sdoslam_test_XXXXXX").string();
    if (mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

inline void WriteText(const std::filesystem::path& path, const std::string& text) {
  std::filesystem::create_directories(path.parent_path());
  std::ofstream(path) << text;
}

inline std::string ReadText(const std::filesystem::path& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// The message of the std::exception (sdoslam::Error derives from it) that `f` throws, or
// "(no error)".
inline std::string MessageOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no error)";
}

// Expects `f` to throw a std::exception whose message mentions `part`.
inline void ExpectErrorMentioning(const std::function<void()>& f, const std::string& part) {
  const std::string message = MessageOf(f);
  EXPECT_NE(message.find(part), std::string::npos) << message;
}

// A YAML "alias bomb": anchors a, b, ... each a list of ten aliases of the one before (the first
// of ten plain values), `levels` of them: 10^levels nodes once expanded, in a few hundred bytes.
inline std::string YamlAliasBomb(int levels) {
  std::string yaml = "a: &a [x, x, x, x, x, x, x, x, x, x]\n";
  for (int level = 1; level < levels; ++level) {
    const std::string name(1, static_cast<char>('a' + level));
    const std::string before(1, static_cast<char>('a' + level - 1));
    yaml += name + ": &" + name + " [";
    for (int k = 0; k < 10; ++k) yaml += (k ? ", *" : "*") + before;
    yaml += "]\n";
  }
  return yaml;
}

// ../shared next to the checkout; tests that need it skip when it is absent.
inline std::filesystem::path SharedDir() { return SDOSLAM_SHARED_DIR; }
inline std::filesystem::path SourceDir() { return SDOSLAM_SOURCE_DIR; }

}  // namespace sdoslam::testing
