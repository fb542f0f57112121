#pragma once

#include <stdexcept>
#include <string>

namespace sdoslam {

// The one exception type the library throws for bad input (missing or malformed files, invalid
// options, ...). Its message is meant for the user as is: it names the file, line or key.
// The library never calls exit(); the `sdoslam` command catches this, prints it and exits 1.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

// Results could not be written (an unwritable --out, a full disk, a failed rename): the inputs
// were fine, the place to write is not. The `sdoslam` command exits 4 on it.
class IoError : public Error {
 public:
  explicit IoError(const std::string& message) : Error(message) {}
};

}  // namespace sdoslam
