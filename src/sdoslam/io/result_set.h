#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

namespace sdoslam {

// A run's results (trajectories, frames.csv, config.yaml, masks/, overlays/, ...) as one set
// that is replaced all or nothing, even by a crash or a power cut.
//
// The writer fills a private staging folder inside the output folder and commits it at the end:
//  1. the staged files are hashed into `manifest.json` (in the staging folder) and synced;
//  2. every new file's place is checked: free, or a file that the earlier set's manifest lists,
//     reached through real folders. A user's file, a folder or a symbolic link in the way (a
//     `masks` that links elsewhere) is an error naming it, and nothing has changed yet;
//  3. a journal, `.sdoslam-commit.json`, naming the staging folder and the earlier set's files
//     that the new set lacks, is written and synced: the commit is now decided;
//  4. the new files are renamed into place (a rename is atomic: no reader sees half a file),
//     the earlier set's leftovers are removed (only files its manifest lists, never through a
//     symbolic link), the new manifest is renamed into place, the journal removed.
// A process killed during step 4 leaves the journal: the next writer, or reader, into that
// folder finishes the commit from the staging folder before anything else, so what anyone reads
// is the earlier set (killed before step 3) or the new one, never a mix. Steps 3-4 also hold
// back a second Ctrl-C until they are done.
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

  // For the crash tests: called with 1, 2, ... after each step of Commit() from the journal on
  // (each rename and removal). A test kills the process there.
  void SetStepHookForTesting(std::function<void(int)> hook) { step_hook_ = std::move(hook); }

 private:
  // The folders the constructor created, outermost first; removed again while empty.
  struct CreatedFolders {
    std::vector<std::filesystem::path> paths;
    ~CreatedFolders();
  };
  void Step();

  std::filesystem::path out_;
  CreatedFolders created_folders_;
  std::filesystem::path staging_;
  bool committed_ = false;
  bool decided_ = false;  // the journal is written: the commit will be finished, here or later
  int lock_fd_ = -1;
  int step_ = 0;
  std::function<void(int)> step_hook_;
};

// Finishes a commit into `out` that a crash cut off (see above); nothing when there is none.
// The caller holds the folder's lock (ResultSetWriter does). Throws IoError when it cannot.
void FinishCutOffCommit(const std::filesystem::path& out);

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
