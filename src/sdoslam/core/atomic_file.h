#pragma once

#include <filesystem>
#include <functional>
#include <ostream>

namespace sdoslam {

// Writes a result file so that an earlier result is never replaced by a half-written one:
// the content goes to a temporary file in the same folder, which is renamed over `path` only
// after it was written completely. Creates missing parent folders. Throws Error on failure.
void WriteFileAtomically(const std::filesystem::path& path,
                         const std::function<void(std::ostream&)>& write);

// Same for writers that take a path (cv::imwrite, ...): `write(temporary_path)` must create the
// file and return true on success. The temporary path keeps the extension of `path` so that
// format-by-extension writers pick the right format.
void WriteFileAtomically(const std::filesystem::path& path,
                         const std::function<bool(const std::filesystem::path&)>& write);

}  // namespace sdoslam
