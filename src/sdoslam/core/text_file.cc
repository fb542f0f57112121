#include "sdoslam/core/text_file.h"

#include <fmt/format.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <sstream>

#include "sdoslam/core/error.h"
#include "sdoslam/core/regular_file.h"
#include "sdoslam/core/timestamps.h"

namespace sdoslam {

void ForEachDataLine(const std::filesystem::path& path,
                     const std::function<void(int, const std::vector<std::string>&)>& on_line) {
  const std::optional<std::string> text = ReadRegularFileIfExists(path);
  if (!text) throw Error("file not found: " + path.string());
  std::istringstream in(*text);
  std::string line;
  std::vector<std::string> tokens;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();  // files written on Windows
    const size_t first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    tokens.clear();
    std::istringstream fields(line);
    for (std::string token; fields >> token;) tokens.push_back(token);
    on_line(line_number, tokens);
  }
}

double ParseDouble(const std::string& token, const std::filesystem::path& path, int line_number,
                   const std::string& what) {
  errno = 0;
  char* end = nullptr;
  const double value = std::strtod(token.c_str(), &end);
  if (end == token.c_str() || *end != '\0' || errno == ERANGE) {
    throw Error(Where(path, line_number) + what + " '" + token + "' is not a number");
  }
  if (!std::isfinite(value)) {
    throw Error(Where(path, line_number) + what + " is " + token + " (must be finite)");
  }
  return value;
}

double ParseTimestamp(const std::string& token, const std::filesystem::path& path, int line_number,
                      const std::string& what) {
  const double value = ParseDouble(token, path, line_number, what);
  if (std::abs(value) > kMaxAbsTimestamp) {
    throw Error(
        fmt::format("{}{} {} is not a time in seconds (beyond +-{:g} s, the year 2286; "
                    "nanoseconds?)",
                    Where(path, line_number), what, token, kMaxAbsTimestamp));
  }
  return value;
}

std::string Where(const std::filesystem::path& path, int line_number) {
  return path.string() + ":" + std::to_string(line_number) + ": ";
}

}  // namespace sdoslam
