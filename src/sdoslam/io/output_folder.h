#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace sdoslam {

// A folder the program writes whole (a synthetic sequence, a converted copy), built beside its
// destination and switched into place in one atomic step, so that a reader, a crash or a power
// cut finds either the earlier folder complete or the new one, never a mix.
//
// "Never delete what is not ours": an existing non-empty folder is replaced only with
// `overwrite`, and only when it is an earlier folder of the same kind that holds nothing but
// the files its marker (`.sdoslam-folder.json`, written last into every such folder) lists.
// Anything else in it (a file the user added, a symbolic link, a folder of someone else's) makes
// the replacement an error that names it. The old folder is then removed file by file from its
// own list, without following symbolic links. `/`, the home folder and the folders the write
// reads (its inputs, any folder that contains one, any folder inside one) are refused as `out`.
//
// Switching: renameat2(RENAME_EXCHANGE) swaps the staged folder with the old one in one step
// (a plain rename when there is no old one); the old one, now under the staging name, is then
// removed. A process killed at any moment leaves at most a hidden sibling
// `.NAME.sdoslam-staging-PID`, which the next write to the same `out` removes.
inline constexpr char kOutputFolderMarker[] = ".sdoslam-folder.json";

struct OutputFolderOptions {
  // What the folder holds ("synth sequence", "tum copy", "omd segment"): an existing folder is
  // replaced only when its marker names the same kind.
  std::string kind;
  bool overwrite = false;  // replace an earlier folder of the same kind
  // Folders (or files) the write reads: `out` may be none of them, nor contain or lie in one.
  std::vector<std::filesystem::path> inputs;

  void Check() const;  // throws Error: an empty kind
};

class OutputFolder {
 public:
  // Checks `out` as described above (throws Error naming what is in the way) and creates the
  // staging folder beside it (throws IoError when it cannot).
  OutputFolder(std::filesystem::path out, OutputFolderOptions options);
  // Without Commit(): removes the staging folder and the parent folders this object created.
  ~OutputFolder();
  OutputFolder(const OutputFolder&) = delete;
  OutputFolder& operator=(const OutputFolder&) = delete;

  const std::filesystem::path& out() const { return out_; }
  // Where the new folder's files go before Commit().
  const std::filesystem::path& staging() const { return staging_; }

  // Writes the marker listing every staged file, syncs, switches the staged folder into place
  // and removes the earlier one. Throws IoError when a step fails (the earlier folder is then
  // still in place, complete).
  void Commit();

  // For the crash tests: called with 1, 2, ... at each step of Commit() (after the sync, after
  // the switch, after each file of the old folder is removed). A test kills the process there.
  void SetStepHookForTesting(std::function<void(int)> hook) { step_hook_ = std::move(hook); }

 private:
  void Step();

  std::filesystem::path out_;
  std::filesystem::path staging_;
  OutputFolderOptions options_;
  std::vector<std::filesystem::path> created_parents_;  // deepest last
  bool committed_ = false;
  int step_ = 0;
  std::function<void(int)> step_hook_;
};

// The checks OutputFolder's constructor makes, without creating anything: for a command that
// must know before long work whether it may write `out` at all.
void CheckOutputFolder(const std::filesystem::path& out, const OutputFolderOptions& options);

// Removes a folder that an OutputFolder of `kind` wrote, file by file from its marker's list.
// Throws Error (and removes nothing) when the folder holds anything else.
void RemoveOutputFolder(const std::filesystem::path& folder, const std::string& kind);

// Throws Error when `out` is `/` or the home folder, or is, contains or lies inside one of
// `inputs` (compared after resolving symbolic links and `..`). `what` names the option
// ("--out") in the message.
void CheckOutputPlace(const std::filesystem::path& out,
                      const std::vector<std::filesystem::path>& inputs, const std::string& what);

}  // namespace sdoslam
