#include "sdoslam/io/output_folder.h"

#include <fcntl.h>
#include <signal.h>
#include <stdio.h>  // renameat2 (glibc 2.28+)
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <system_error>

#include "sdoslam/core/atomic_file.h"
#include "sdoslam/core/error.h"
#include "sdoslam/core/interrupt.h"

namespace sdoslam {
namespace fs = std::filesystem;
namespace {

constexpr char kMarkerFormat[] = "sdoslam output folder";
constexpr char kStagingInfix[] = ".sdoslam-staging-";

std::string ErrorText(int error) { return std::strerror(error); }

// lstat: what is at `path` itself, a symbolic link not followed.
fs::file_status OwnStatus(const fs::path& path) {
  std::error_code ec;
  return fs::symlink_status(path, ec);
}

fs::path Resolved(const fs::path& path) {
  std::error_code ec;
  fs::path resolved = fs::weakly_canonical(fs::absolute(path, ec), ec);
  return ec ? fs::absolute(path).lexically_normal() : resolved;
}

// True when `inner` is `outer` or lies inside it (both resolved).
bool IsWithin(const fs::path& inner, const fs::path& outer) {
  auto i = inner.begin();
  for (auto o = outer.begin(); o != outer.end(); ++o, ++i) {
    if (o->empty()) continue;  // a trailing separator
    if (i == inner.end() || *i != *o) return false;
  }
  return true;
}

// `.NAME.sdoslam-staging-` for `out`: the prefix of its staging folders' names.
std::string StagingPrefix(const fs::path& out) {
  // Appended piece by piece: GCC 12 warns (-Wrestrict, a false positive) on `"." + string`.
  std::string prefix = ".";
  prefix += out.filename().string();
  prefix += kStagingInfix;
  return prefix;
}

fs::path ParentOf(const fs::path& out) {
  return out.has_parent_path() ? out.parent_path() : fs::path(".");
}

struct Marker {
  std::string kind;
  std::vector<std::string> files;  // relative, '/'-separated
};

// Reads `folder`'s marker; nullopt when it has none, is not a regular file or not ours.
std::optional<Marker> ReadMarker(const fs::path& folder) {
  const fs::path path = folder / kOutputFolderMarker;
  if (!fs::is_regular_file(OwnStatus(path))) return std::nullopt;
  std::error_code ec;
  if (fs::file_size(path, ec) > (64u << 20)) return std::nullopt;
  std::ifstream in(path);
  try {
    const nlohmann::json json = nlohmann::json::parse(in);
    if (json.at("format").get<std::string>() != kMarkerFormat) return std::nullopt;
    Marker marker;
    marker.kind = json.at("kind").get<std::string>();
    for (const auto& f : json.at("files")) {
      std::string file = f.get<std::string>();
      const fs::path p(file);
      if (file.empty() || p.is_absolute() ||
          std::any_of(p.begin(), p.end(), [](const fs::path& c) { return c == ".."; }))
        return std::nullopt;  // a list that leaves the folder is nobody's list of ours
      marker.files.push_back(std::move(file));
    }
    return marker;
  } catch (const nlohmann::json::exception&) {
    return std::nullopt;
  }
}

// Throws Error unless `folder` holds only what its marker of `kind` lists (and the folders on
// the way to those files): nothing the user added, no symbolic link.
void CheckOwned(const fs::path& folder, const std::string& kind) {
  const std::optional<Marker> marker = ReadMarker(folder);
  const std::string advice =
      ": --overwrite replaces only a folder that sdoslam wrote and that "
      "holds nothing else; move it away or choose another --out";
  if (!marker) {
    throw Error(folder.string() + " was not written by sdoslam (no " + kOutputFolderMarker + ")" +
                advice);
  }
  if (marker->kind != kind) {
    throw Error(folder.string() + " holds a " + marker->kind + ", not a " + kind + advice);
  }
  std::set<std::string> files(marker->files.begin(), marker->files.end());
  files.insert(kOutputFolderMarker);
  std::set<std::string> folders;
  for (const std::string& f : files) {
    for (fs::path p = fs::path(f).parent_path(); !p.empty(); p = p.parent_path())
      folders.insert(p.generic_string());
  }
  std::error_code ec;
  // recursive_directory_iterator does not descend into symbolic links to folders by default.
  for (fs::recursive_directory_iterator it(folder, ec), end; it != end; it.increment(ec)) {
    if (ec) break;
    const std::string relative = it->path().lexically_relative(folder).generic_string();
    const fs::file_status status = it->symlink_status(ec);
    const bool listed = fs::is_regular_file(status) ? files.count(relative) > 0
                        : fs::is_directory(status)  ? folders.count(relative) > 0
                                                    : false;
    if (!listed) {
      throw Error(folder.string() + " holds " + it->path().string() +
                  ", which sdoslam did not write" + advice);
    }
  }
  if (ec) throw IoError("cannot list " + folder.string() + ": " + ec.message());
}

// Removes a folder of ours by its marker's list: files, then the folders that held them (only
// when empty), then the marker and the folder. Symbolic links are never followed: a listed
// path that is not a regular file, or lies under something that is not a real folder, is left.
// `after_each` runs after each removal (the crash tests' hook).
void RemoveOwned(const fs::path& folder, const std::function<void()>& after_each) {
  const std::optional<Marker> marker = ReadMarker(folder);
  std::error_code ec;
  if (!marker) {
    // Never listed: a staging folder cut off before its marker. Ours by its unique name;
    // remove_all removes a symbolic link itself, never what it points to.
    fs::remove_all(folder, ec);
    return;
  }
  std::set<std::string> folders;
  for (const std::string& f : marker->files) {
    bool through_real_folders = true;
    for (fs::path p = fs::path(f).parent_path(); !p.empty(); p = p.parent_path()) {
      folders.insert(p.generic_string());
      if (!fs::is_directory(OwnStatus(folder / p))) through_real_folders = false;
    }
    const fs::path path = folder / f;
    if (through_real_folders && fs::is_regular_file(OwnStatus(path))) {
      fs::remove(path, ec);
      after_each();
    }
  }
  // Deepest first: a '/'-separated path sorts after its parent, so reverse order works.
  for (auto it = folders.rbegin(); it != folders.rend(); ++it) {
    const fs::path path = folder / *it;
    if (fs::is_directory(OwnStatus(path)))
      ::rmdir(path.c_str());  // fails, harmlessly, if not empty
  }
  fs::remove(folder / kOutputFolderMarker, ec);
  if (::rmdir(folder.c_str()) != 0 && errno != ENOENT) {
    // Something appeared in it that is not ours: leave it where it is, and say so.
    throw IoError("left " + folder.string() + " in place: it holds files sdoslam did not write");
  }
}

bool ProcessIsAlive(long pid) {
  if (pid <= 0) return false;
  return ::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM;
}

// Removes the staging folders of `out` that processes no longer alive left behind.
void RemoveLeftovers(const fs::path& out) {
  const std::string prefix = StagingPrefix(out);
  std::error_code ec;
  std::vector<fs::path> leftovers;
  for (const auto& entry : fs::directory_iterator(ParentOf(out), ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(prefix, 0) != 0) continue;
    char* end = nullptr;
    const long pid = std::strtol(name.c_str() + prefix.size(), &end, 10);
    if (end == nullptr || *end != '\0' || ProcessIsAlive(pid)) continue;
    if (fs::is_directory(entry.symlink_status(ec))) leftovers.push_back(entry.path());
  }
  for (const fs::path& leftover : leftovers) {
    try {
      RemoveOwned(leftover, [] {});
    } catch (const IoError&) {
      // Holds something not ours: it stays.
    }
  }
}

// rename(2) variants; EINVAL/ENOSYS: the file system does not support the flag.
int RenameWithFlags(const fs::path& from, const fs::path& to, unsigned flags) {
  return ::renameat2(AT_FDCWD, from.c_str(), AT_FDCWD, to.c_str(), flags) == 0 ? 0 : errno;
}

}  // namespace

void OutputFolderOptions::Check() const {
  if (kind.empty()) throw Error("OutputFolderOptions: kind is empty");
}

void CheckOutputPlace(const fs::path& out, const std::vector<fs::path>& inputs,
                      const std::string& what) {
  if (out.empty()) throw Error(what + " is empty: give a folder");
  const fs::path resolved = Resolved(out);
  if (resolved == resolved.root_path())
    throw Error(what + " " + out.string() + " is the root folder: give a folder of its own");
  if (const char* home = std::getenv("HOME"); home != nullptr && *home != '\0') {
    if (resolved == Resolved(home))
      throw Error(what + " " + out.string() + " is the home folder: give a folder of its own");
  }
  for (const fs::path& input : inputs) {
    if (input.empty()) continue;
    const fs::path in = Resolved(input);
    if (resolved == in) throw Error(what + " " + out.string() + " is the input " + input.string());
    if (IsWithin(resolved, in))
      throw Error(what + " " + out.string() + " lies inside the input " + input.string());
    if (IsWithin(in, resolved))
      throw Error(what + " " + out.string() + " contains the input " + input.string());
  }
}

void CheckOutputFolder(const fs::path& out, const OutputFolderOptions& options) {
  options.Check();
  CheckOutputPlace(out, options.inputs, "--out");
  const fs::file_status status = OwnStatus(out);
  if (fs::is_symlink(status)) {
    throw Error(out.string() +
                " is a symbolic link: give the folder it points to, or another --out");
  }
  if (fs::exists(status) && !fs::is_directory(status))
    throw Error(out.string() + ": --out names a file, not a folder");
  std::error_code ec;
  if (fs::is_directory(status) && !fs::is_empty(out, ec)) {
    if (!options.overwrite)
      throw Error(out.string() + " exists and is not empty (pass --overwrite to replace it)");
    CheckOwned(out, options.kind);
  }
}

void RemoveOutputFolder(const fs::path& folder, const std::string& kind) {
  CheckOwned(folder, kind);
  RemoveOwned(folder, [] {});
}

OutputFolder::OutputFolder(fs::path out, OutputFolderOptions options)
    : out_(std::move(out)), options_(std::move(options)) {
  if (out_.empty()) throw Error("--out is empty: give a folder");
  out_ = out_.lexically_normal();
  if (out_.filename().empty() && out_.has_parent_path()) out_ = out_.parent_path();  // "d/"
  if (out_.filename() == "." || out_.filename() == "..") {
    // The staging folder goes beside `out`, in its parent: "." has to be named to have one.
    out_ = fs::absolute(out_).lexically_normal();
    if (out_.filename().empty()) out_ = out_.parent_path();
  }
  CheckOutputFolder(out_, options_);
  std::error_code ec;

  // Parent folders, each remembered so that a failed write removes what it created.
  std::vector<fs::path> missing;
  for (fs::path p = ParentOf(out_); !p.empty() && !fs::exists(OwnStatus(p)); p = p.parent_path())
    missing.push_back(p);
  for (auto it = missing.rbegin(); it != missing.rend(); ++it) {
    if (!fs::create_directory(*it, ec) && ec)
      throw IoError("cannot create the folder " + it->string() + ": " + ec.message());
    created_parents_.push_back(*it);
  }
  RemoveLeftovers(out_);
  staging_ = ParentOf(out_) / (StagingPrefix(out_) + std::to_string(::getpid()));
  if (!fs::create_directory(staging_, ec)) {
    throw IoError("cannot create " + staging_.string() +
                  " beside the output folder: " + (ec ? ec.message() : std::string("it exists")));
  }
}

OutputFolder::~OutputFolder() {
  std::error_code ec;
  if (!committed_ && !staging_.empty()) fs::remove_all(staging_, ec);
  if (!committed_) {
    for (auto it = created_parents_.rbegin(); it != created_parents_.rend(); ++it)
      ::rmdir(it->c_str());  // only while empty
  }
}

void OutputFolder::Step() {
  ++step_;
  if (step_hook_) step_hook_(step_);
}

void OutputFolder::Commit() {
  if (committed_) throw Error("OutputFolder: committed twice");
  nlohmann::ordered_json files = nlohmann::ordered_json::array();
  std::vector<std::string> listed;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(staging_, ec), end; it != end; it.increment(ec)) {
    if (ec) break;
    if (fs::is_regular_file(it->symlink_status(ec)))
      listed.push_back(it->path().lexically_relative(staging_).generic_string());
  }
  if (ec) throw IoError("cannot list " + staging_.string() + ": " + ec.message());
  std::sort(listed.begin(), listed.end());
  for (const std::string& f : listed) files.push_back(f);
  {
    nlohmann::ordered_json marker;
    marker["format"] = kMarkerFormat;
    marker["kind"] = options_.kind;
    marker["note"] =
        "written by sdoslam; --overwrite replaces this folder only while it holds "
        "nothing but these files";
    marker["files"] = files;
    std::ofstream out(staging_ / kOutputFolderMarker, std::ios::binary | std::ios::trunc);
    out << marker.dump(1) << '\n';
    out.flush();
    if (!out) throw IoError("cannot write " + (staging_ / kOutputFolderMarker).string());
  }
  SyncFileSystemOf(staging_);
  Step();

  // A second Ctrl-C waits until the switch is done (a hard kill cannot cut it in half either).
  AbortDeferral defer_abort;
  const fs::file_status status = OwnStatus(out_);
  const bool replace = fs::is_directory(status) && !fs::is_empty(out_, ec);
  if (replace) {
    CheckOwned(out_, options_.kind);  // again: it may have changed while the folder was built
    int error = RenameWithFlags(staging_, out_, RENAME_EXCHANGE);
    if (error == EINVAL || error == ENOSYS) {
      // No exchange on this file system: two renames, the old folder first moved under the
      // staging-like name that the next write removes.
      const fs::path old =
          ParentOf(out_) / (StagingPrefix(out_) + "0" + std::to_string(::getpid()));
      error = RenameWithFlags(out_, old, 0);
      if (error == 0) error = RenameWithFlags(staging_, out_, 0);
      if (error == 0) {
        fs::rename(old, staging_, ec);
        if (ec) throw IoError("cannot move " + old.string() + ": " + ec.message());
      }
    }
    if (error != 0) {
      throw IoError("cannot switch " + staging_.string() + " into place at " + out_.string() +
                    ": " + ErrorText(error));
    }
  } else {
    // No old folder, or an empty one: rename(2) replaces an empty folder atomically.
    int error = fs::exists(status) ? RenameWithFlags(staging_, out_, 0)
                                   : RenameWithFlags(staging_, out_, RENAME_NOREPLACE);
    if (error == EINVAL || error == ENOSYS) error = RenameWithFlags(staging_, out_, 0);
    if (error != 0) {
      throw IoError("cannot move " + staging_.string() + " to " + out_.string() + ": " +
                    ErrorText(error));
    }
  }
  committed_ = true;
  SyncToDisk(ParentOf(out_));
  Step();
  if (replace) RemoveOwned(staging_, [this] { Step(); });
}

}  // namespace sdoslam
