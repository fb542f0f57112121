#pragma once

#include <gtest/gtest.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/wait.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
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

// Every regular file under `folder` (relative '/'-separated path -> content), symbolic links
// not followed: a folder's state, to compare before and after a command.
inline std::map<std::string, std::string> FilesUnder(const std::filesystem::path& folder) {
  std::map<std::string, std::string> files;
  for (const auto& e : std::filesystem::recursive_directory_iterator(folder)) {
    if (std::filesystem::is_regular_file(e.symlink_status()))
      files[e.path().lexically_relative(folder).generic_string()] = ReadText(e.path());
  }
  return files;
}

// What a shell command printed (stdout and stderr together) and its exit code (-1: it did not
// exit normally).
struct CommandResult {
  int exit_code;
  std::string output;
};

inline CommandResult RunCommand(const std::string& command_line) {
  std::string command = command_line;
  command += " 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return {-1, "popen failed"};
  std::string output;
  char buffer[4096];
  size_t n;
  while ((n = fread(buffer, 1, sizeof(buffer), pipe)) > 0) output.append(buffer, n);
  const int status = pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, output};
}

// ../shared next to the checkout; tests that need it skip when it is absent.
inline std::filesystem::path SharedDir() { return SDOSLAM_SHARED_DIR; }
inline std::filesystem::path SourceDir() { return SDOSLAM_SOURCE_DIR; }

}  // namespace sdoslam::testing
