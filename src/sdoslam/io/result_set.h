#pragma once

#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

namespace sdoslam {

// A run's results (trajectories, frames.csv, config.yaml, masks/, overlays/, ...) as one set
// that is replaced all or nothing.
//
// The writer fills a private staging folder inside the output folder and commits it at the end:
// every staged file is renamed into place (a rename within one file system is atomic, so no
// reader ever sees a half-written file), results of the earlier set that the new one lacks are
// removed, and `manifest.json`, naming every file with its size and SHA-256, is renamed into
// place last. Readers (`eval`, `eval-masks`) check the manifest and refuse a set whose files do
// not match it. The commit is short (renames only) and blocks SIGINT/SIGTERM while it runs, so
// an interrupt leaves either the old set or the new one; only a crash inside those milliseconds
// leaves a set the readers refuse, with the complete new set still in the staging folder.
//
// Why not one rename of a folder: users find their results in --out itself, and a folder cannot
// be swapped atomically with the folder that contains it.

inline constexpr char kManifestName[] = "manifest.json";

struct ResultFileEntry {
  std::string path;  // relative to the output folder, '/'-separated
  uintmax_t size = 0;
  std::string sha256;  // lowercase hex
};

struct ResultManifest {
  std::string status;   // "complete" or "interrupted"
  nlohmann::json info;  // what the writer adds: frames processed, mode, ...
  std::vector<ResultFileEntry> files;

  const ResultFileEntry* Find(const std::string& relative_path) const;
};

class ResultSetWriter {
 public:
  // Creates `out` if missing and checks it for writing with a probe file, so that a bad --out
  // fails before any work. Takes an exclusive lock on the folder (a second run into the same
  // folder is an error) and removes staging folders that runs cut off earlier left behind.
  // Throws IoError naming the folder.
  explicit ResultSetWriter(std::filesystem::path out);
  // Without Commit(): removes the staging folder (the earlier set stays untouched), and `out`
  // too when this writer created it and it is still empty.
  ~ResultSetWriter();
  ResultSetWriter(const ResultSetWriter&) = delete;
  ResultSetWriter& operator=(const ResultSetWriter&) = delete;

  const std::filesystem::path& out() const { return out_; }
  const std::filesystem::path& staging() const { return staging_; }

  // Where to write `relative_path` of the new set (its parent folders are created).
  std::filesystem::path Stage(const std::string& relative_path) const;
  // Writes text content to a staged file; throws IoError on failure.
  void WriteText(const std::string& relative_path, const std::string& content) const;

  // Hashes the staged files, syncs them to disk, and replaces the earlier set by the new one as
  // described above. `status` is "complete" or "interrupted". Returns the manifest written.
  ResultManifest Commit(const std::string& status, const nlohmann::json& info);

 private:
  std::filesystem::path out_;
  std::filesystem::path staging_;
  bool created_out_ = false;
  bool committed_ = false;
  int lock_fd_ = -1;
};

// Reads `out`/manifest.json. Throws Error when absent or malformed.
ResultManifest ReadResultManifest(const std::filesystem::path& out);

// Checks a whole result set: the manifest exists, and every file it names exists with its size
// and hash. Throws Error naming the first mismatch and what to do about it.
ResultManifest VerifyResultSet(const std::filesystem::path& out);

// For readers given a single file (eval --est): when the file's folder holds a result set's
// manifest, checks the file against it (and returns the manifest); when a run into that folder
// was cut off before committing, refuses; a file from elsewhere (no manifest) passes unchecked.
std::optional<ResultManifest> VerifyResultFile(const std::filesystem::path& file);

// SHA-256 of a file's content as lowercase hex (OpenSSL). Throws IoError when unreadable.
std::string Sha256OfFile(const std::filesystem::path& path);

}  // namespace sdoslam
