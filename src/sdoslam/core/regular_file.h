#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

namespace sdoslam {

// Every file the program reads as a file (configs, lists, trajectories, images, vocabularies,
// models, JSON) must be a regular file: opening a FIFO blocks until someone writes to it,
// /dev/zero never ends (a reader grew to 4 GB before bad_alloc), and a folder reads as an
// error that names no cause. These refuse anything else at once with "<path>: not a regular
// file" (symbolic links are followed), and keep the caller's own message for a missing file.

// Larger than any list, trajectory, image or vocabulary a user could mean; a sanity limit, so
// that a wrong file fails with its size instead of filling the memory.
inline constexpr uint64_t kMaxInputFileBytes = uint64_t{1} << 30;

// Throws Error("<path>: not a regular file") when `path` exists and is anything else (folder,
// FIFO, device, socket). Missing and regular files pass: for readers that open the file
// themselves (a stream, a library that takes a path) and name a missing file their own way.
void RejectNonRegularFile(const std::filesystem::path& path);

// The whole content of a regular file, or nullopt when `path` does not exist. The file is
// opened without blocking and checked after opening, so a file swapped for a FIFO between a
// check and the read cannot hang the reader. Throws Error naming the path when it is not a
// regular file, is larger than `max_bytes`, or cannot be read.
std::optional<std::string> ReadRegularFileIfExists(const std::filesystem::path& path,
                                                   uint64_t max_bytes = kMaxInputFileBytes);

// As ReadRegularFileIfExists; a missing file throws Error("<path>: not found").
std::string ReadRegularFile(const std::filesystem::path& path,
                            uint64_t max_bytes = kMaxInputFileBytes);

// The first `bytes` bytes (all of a shorter file), or nullopt when `path` does not exist;
// throws as ReadRegularFileIfExists. For headers, read without reading the whole file.
std::optional<std::string> ReadRegularFileHead(const std::filesystem::path& path, size_t bytes);

}  // namespace sdoslam
