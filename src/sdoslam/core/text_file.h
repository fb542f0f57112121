#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace sdoslam {

// Calls `on_line(line_number, tokens)` for every data line of a whitespace-separated text file
// (the TUM file lists and trajectories). Blank lines and lines starting with '#' are skipped;
// line numbers are 1-based so that messages match what an editor shows.
// Throws Error naming the file when it is missing, not a regular file (regular_file.h) or
// cannot be read.
void ForEachDataLine(
    const std::filesystem::path& path,
    const std::function<void(int line_number, const std::vector<std::string>& tokens)>& on_line);

// Parses a finite double; throws Error("<file>:<line>: <what> ...") otherwise.
double ParseDouble(const std::string& token, const std::filesystem::path& path, int line_number,
                   const std::string& what);

// Parses a timestamp in seconds: ParseDouble, and within +-kMaxAbsTimestamp (timestamps.h);
// throws Error("<file>:<line>: <what> ...") otherwise.
double ParseTimestamp(const std::string& token, const std::filesystem::path& path, int line_number,
                      const std::string& what);

// "<file>:<line>: " prefix for messages.
std::string Where(const std::filesystem::path& path, int line_number);

}  // namespace sdoslam
