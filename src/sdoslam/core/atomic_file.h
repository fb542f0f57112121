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

// Flushes one file or folder to disk (fsync). Throws IoError naming it.
void SyncToDisk(const std::filesystem::path& path);

// Flushes every file of `folder`'s file system in one call (syncfs): for a folder of 1,000s of
// files, where one fsync each would cost seconds. Throws IoError naming it.
void SyncFileSystemOf(const std::filesystem::path& folder);

}  // namespace sdoslam
