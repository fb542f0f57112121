#include "sdoslam/io/result_set.h"

#include <fcntl.h>
#include <openssl/evp.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <functional>
#include <iterator>
#include <memory>
#include <set>
#include <system_error>

#include "sdoslam/core/atomic_file.h"
#include "sdoslam/core/error.h"
#include "sdoslam/core/interrupt.h"
#include "sdoslam/core/regular_file.h"
#include "sdoslam/io/output_folder.h"

namespace sdoslam {
namespace fs = std::filesystem;
namespace {

constexpr char kStagingPrefix[] = ".sdoslam-staging-";
constexpr char kFormat[] = "sdoslam result set";
constexpr int kFormatVersion = 1;

constexpr char kJournalName[] = ".sdoslam-commit.json";
constexpr char kJournalFormat[] = "sdoslam result commit";

std::string ErrnoText() { return std::strerror(errno); }

bool IsStagingName(const std::string& name) { return name.rfind(kStagingPrefix, 0) == 0; }

std::vector<fs::path> StagingFolders(const fs::path& out) {
  std::vector<fs::path> found;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(out, ec)) {
    if (entry.is_directory(ec) && IsStagingName(entry.path().filename().string()))
      found.push_back(entry.path());
  }
  return found;
}

void Rename(const fs::path& from, const fs::path& to) {
  std::error_code ec;
  fs::rename(from, to, ec);
  // The message comes from this rename's own error code, not from errno of a later call.
  if (ec)
    throw IoError("cannot move " + from.string() + " to " + to.string() + ": " + ec.message());
}

// Throws IoError unless every folder between `out` and `relative`'s file is absent or a real
// folder: a result is never written or removed through a symbolic link.
void CheckRealFolders(const fs::path& out, const std::string& relative) {
  std::error_code ec;
  fs::path at = out;
  const fs::path rel(relative);
  for (auto it = rel.begin(); std::next(it) != rel.end(); ++it) {
    at /= *it;
    const fs::file_status status = fs::symlink_status(at, ec);
    if (!fs::exists(status)) return;
    if (!fs::is_directory(status)) {
      throw IoError(at.string() + " is in the way: " +
                    (fs::is_symlink(status) ? "a symbolic link" : "not a folder") +
                    " where sdoslam writes its " + it->string() +
                    "/; move it away, or choose another --out. The earlier results are unchanged");
    }
  }
}

// Writes `text` to `path` through a synced temporary file and a rename, then syncs the folder:
// after it returns, the file is on disk whole, whatever happens next.
void WriteFileAtomicallySynced(const fs::path& path, const std::string& text) {
  const fs::path tmp = path.string() + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << text;
    out.flush();
    if (!out) throw IoError("cannot write " + tmp.string() + " (disk full?)");
  }
  SyncToDisk(tmp);
  Rename(tmp, path);
  SyncToDisk(path.parent_path());
}

// Carries out (or finishes) the commit that `out`'s journal describes. Every step can be
// repeated: a file already moved is not in the staging folder any more, a stale file already
// removed is gone, and once the new manifest is in place only the clean-up is left.
void ApplyJournal(const fs::path& out, const std::function<void()>& step) {
  const fs::path journal_path = out / kJournalName;
  nlohmann::json journal;
  std::string staging_name;
  try {
    std::ifstream in(journal_path);
    journal = nlohmann::json::parse(in);
    if (journal.at("format").get<std::string>() != kJournalFormat) throw Error("format");
    staging_name = journal.at("staging").get<std::string>();
    for (const auto& item : journal.at("stale")) item.get<std::string>();  // all strings
  } catch (const std::exception&) {
    throw IoError(journal_path.string() +
                  " is damaged: the commit it describes cannot be finished; remove the folder's "
                  "results by hand and rerun");
  }
  if (!IsStagingName(staging_name) || staging_name.find('/') != std::string::npos)
    throw IoError(journal_path.string() + ": names no staging folder of sdoslam's");
  const fs::path staging = out / staging_name;
  std::error_code ec;
  if (fs::is_regular_file(fs::symlink_status(staging / kManifestName, ec))) {
    const ResultManifest fresh = ReadResultManifest(staging);
    fs::remove(out / kManifestName, ec);  // the old set is no longer vouched for
    step();
    for (const ResultFileEntry& f : fresh.files) {
      const fs::path from = staging / f.path;
      if (!fs::exists(fs::symlink_status(from, ec))) continue;  // moved before the crash
      CheckRealFolders(out, f.path);
      const fs::path target = out / f.path;
      fs::create_directories(target.parent_path(), ec);
      Rename(from, target);
      step();
    }
    std::set<fs::path> emptied;
    for (const auto& item : journal.at("stale")) {
      const std::string path = item.get<std::string>();
      if (fresh.Find(path) || path.find("..") != std::string::npos || path.empty() ||
          path[0] == '/')
        continue;
      try {
        CheckRealFolders(out, path);
      } catch (const IoError&) {
        continue;  // behind a symbolic link now: not ours to touch
      }
      if (fs::is_regular_file(fs::symlink_status(out / path, ec))) {
        fs::remove(out / path, ec);
        step();
      }
      for (fs::path p = fs::path(path).parent_path(); !p.empty(); p = p.parent_path())
        emptied.insert(p);
    }
    for (auto it = emptied.rbegin(); it != emptied.rend(); ++it) {
      if (fs::is_directory(fs::symlink_status(out / *it, ec))) ::rmdir((out / *it).c_str());
    }
    Rename(staging / kManifestName, out / kManifestName);
    SyncToDisk(out);
    step();
  }
  fs::remove(journal_path, ec);
  SyncToDisk(out);
  fs::remove_all(staging, ec);
}

// Ordered so that a reader sees format, status and info before the long list of files.
nlohmann::ordered_json ToJson(const ResultManifest& manifest) {
  nlohmann::ordered_json files = nlohmann::ordered_json::array();
  for (const ResultFileEntry& f : manifest.files)
    files.push_back({{"path", f.path}, {"size", f.size}, {"sha256", f.sha256}});
  nlohmann::ordered_json json;
  json["format"] = kFormat;
  json["format_version"] = kFormatVersion;
  json["status"] = manifest.status;
  json["info"] = nlohmann::ordered_json::parse(manifest.info.dump());
  json["files"] = files;
  return json;
}

}  // namespace

void FinishCutOffCommit(const fs::path& out) {
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(out / kJournalName, ec))) return;
  ApplyJournal(out, [] {});
}

const ResultFileEntry* ResultManifest::Find(const std::string& relative_path) const {
  for (const ResultFileEntry& f : files)
    if (f.path == relative_path) return &f;
  return nullptr;
}

std::string Sha256OfFile(const fs::path& path) {
  RejectNonRegularFile(path);  // a FIFO in a result folder would block the reader
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path.string() + ": cannot read");
  std::unique_ptr<EVP_MD_CTX, decltype(&EVP_MD_CTX_free)> context(EVP_MD_CTX_new(),
                                                                  EVP_MD_CTX_free);
  if (!context || EVP_DigestInit_ex(context.get(), EVP_sha256(), nullptr) != 1)
    throw IoError("SHA-256 is not available (OpenSSL)");
  std::array<char, 1 << 16> buffer;
  while (in) {
    in.read(buffer.data(), buffer.size());
    if (in.gcount() > 0) EVP_DigestUpdate(context.get(), buffer.data(), in.gcount());
  }
  if (in.bad()) throw IoError(path.string() + ": read error");
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  EVP_DigestFinal_ex(context.get(), digest, &length);
  static const char* kHex = "0123456789abcdef";
  std::string hex;
  for (unsigned int i = 0; i < length; ++i) {
    hex += kHex[digest[i] >> 4];
    hex += kHex[digest[i] & 15];
  }
  return hex;
}

ResultSetWriter::ResultSetWriter(fs::path out) : out_(std::move(out)) {
  std::error_code ec;
  if (out_.empty()) throw Error("--out is empty: give a folder");
  CheckOutputPlace(out_, {}, "--out");
  if (fs::exists(out_, ec) && !fs::is_directory(out_, ec))
    throw IoError(out_.string() + ": --out names a file, not a folder");
  if (!fs::exists(out_, ec)) {
    // Each missing level remembered, so that a failed run removes every folder it created.
    std::vector<fs::path> missing;
    for (fs::path p = out_; !p.empty() && !fs::exists(fs::symlink_status(p, ec));
         p = p.parent_path()) {
      missing.push_back(p);
      if (p == p.parent_path()) break;
    }
    for (auto it = missing.rbegin(); it != missing.rend(); ++it) {
      if (!fs::create_directory(*it, ec) && ec)
        throw IoError("cannot create the output folder " + it->string() + ": " + ec.message());
      created_folders_.paths.push_back(*it);
    }
  }
  // A probe file finds a read-only folder or file system now, not after the last frame.
  const fs::path probe = out_ / (".sdoslam-probe-" + std::to_string(::getpid()));
  {
    std::ofstream test(probe, std::ios::binary | std::ios::trunc);
    if (!test || !(test << "probe") || !test.flush()) {
      const std::string why = ErrnoText();
      fs::remove(probe, ec);
      throw IoError("cannot write into the output folder " + out_.string() + ": " + why);
    }
  }
  fs::remove(probe, ec);

  lock_fd_ = ::open(out_.c_str(), O_DIRECTORY | O_RDONLY | O_CLOEXEC);
  if (lock_fd_ < 0) throw IoError("cannot open " + out_.string() + ": " + ErrnoText());
  if (::flock(lock_fd_, LOCK_EX | LOCK_NB) != 0) {
    ::close(lock_fd_);
    lock_fd_ = -1;
    throw IoError(out_.string() + ": another sdoslam run is writing into this folder");
  }
  // Holding the lock: a commit that a crash cut off is finished first (its staging folder holds
  // the complete new set), then every other staging folder is from a run that was cut off.
  try {
    FinishCutOffCommit(out_);
  } catch (...) {
    ::close(lock_fd_);
    lock_fd_ = -1;
    throw;
  }
  for (const fs::path& stale : StagingFolders(out_)) fs::remove_all(stale, ec);

  staging_ = out_ / (std::string(kStagingPrefix) + std::to_string(::getpid()));
  fs::create_directory(staging_, ec);
  if (ec) {
    ::close(lock_fd_);  // the destructor does not run for a constructor that throws
    lock_fd_ = -1;
    throw IoError("cannot create " + staging_.string() + ": " + ec.message());
  }
}

ResultSetWriter::~ResultSetWriter() {
  std::error_code ec;
  // Once the journal is written the staging folder is the new set: the next run finishes it.
  if (!committed_ && !decided_ && !staging_.empty()) fs::remove_all(staging_, ec);
  if (lock_fd_ >= 0) ::close(lock_fd_);
}

ResultSetWriter::CreatedFolders::~CreatedFolders() {
  // rmdir(2) removes a folder only while it is empty: a folder that got results stays. Runs
  // also when the constructor throws, so a failed `--out a/b/c` leaves no `a/` behind.
  for (auto it = paths.rbegin(); it != paths.rend(); ++it) ::rmdir(it->c_str());
}

fs::path ResultSetWriter::Stage(const std::string& relative_path) const {
  const fs::path path = staging_ / relative_path;
  std::error_code ec;
  fs::create_directories(path.parent_path(), ec);
  if (ec) throw IoError("cannot create " + path.parent_path().string() + ": " + ec.message());
  return path;
}

void ResultSetWriter::WriteText(const std::string& relative_path,
                                const std::string& content) const {
  const fs::path path = Stage(relative_path);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << content;
  out.flush();
  if (!out) throw IoError("cannot write " + path.string() + " (disk full?)");
}

void ResultSetWriter::Step() {
  ++step_;
  if (step_hook_) step_hook_(step_);
}

ResultManifest ResultSetWriter::Commit(const std::string& status, const nlohmann::json& info) {
  if (committed_) throw Error("ResultSetWriter: committed twice");
  ResultManifest manifest;
  manifest.status = status;
  manifest.info = info;
  std::error_code ec;
  for (const auto& entry : fs::recursive_directory_iterator(staging_)) {
    if (!entry.is_regular_file()) continue;
    ResultFileEntry file;
    file.path = fs::relative(entry.path(), staging_).generic_string();
    file.size = entry.file_size();
    file.sha256 = Sha256OfFile(entry.path());
    manifest.files.push_back(std::move(file));
  }
  std::sort(manifest.files.begin(), manifest.files.end(),
            [](const auto& a, const auto& b) { return a.path < b.path; });
  WriteText(kManifestName, ToJson(manifest).dump(1) + "\n");
  SyncFileSystemOf(staging_);
  Step();

  // Before anything in `out` changes: every new file's place must be free or hold a file of the
  // earlier set, reached through real folders. A user's file, a folder or a symbolic link
  // there (a `masks` that links elsewhere) is refused, naming it, with the earlier set intact.
  std::optional<ResultManifest> old;
  if (fs::exists(fs::symlink_status(out_ / kManifestName, ec))) old = ReadResultManifest(out_);
  for (const ResultFileEntry& f : manifest.files) {
    const fs::path target = out_ / f.path;
    CheckRealFolders(out_, f.path);
    const fs::file_status status = fs::symlink_status(target, ec);
    if (!fs::exists(status)) continue;
    if (!fs::is_regular_file(status) || !old || !old->Find(f.path)) {
      throw IoError(target.string() + " is in the way: sdoslam did not write it (" +
                    std::string(fs::is_directory(status)      ? "a folder"
                                : fs::is_symlink(status)      ? "a symbolic link"
                                : fs::is_regular_file(status) ? "not in manifest.json"
                                                              : "not a regular file") +
                    "); move it away, or choose another --out. The earlier results are unchanged");
    }
  }
  // The earlier set's files that the new one lacks: removed, and nothing else.
  nlohmann::json stale = nlohmann::json::array();
  if (old) {
    for (const ResultFileEntry& f : old->files)
      if (!manifest.Find(f.path)) stale.push_back(f.path);
  }

  // The journal names the complete staged set: from the moment it is in place, the commit is
  // decided, and a crash anywhere after it is finished by the next writer or reader.
  WriteFileAtomicallySynced(
      out_ / kJournalName,
      nlohmann::json{
          {"format", kJournalFormat}, {"staging", staging_.filename().string()}, {"stale", stale}}
          .dump(1));
  decided_ = true;
  Step();
  // From here on only renames and removals: a second interrupt waits until they are done.
  AbortDeferral defer_abort;
  ApplyJournal(out_, [this] { Step(); });
  committed_ = true;
  return manifest;
}

ResultManifest ReadResultManifest(const fs::path& out) {
  const fs::path path = out / kManifestName;
  const std::string text = ReadRegularFile(path, uint64_t{256} << 20);
  nlohmann::json json;
  try {
    json = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw Error(path.string() + ": not valid JSON (" + e.what() + ")");
  }
  ResultManifest manifest;
  try {
    if (json.at("format").get<std::string>() != kFormat)
      throw Error(path.string() + ": not an sdoslam result manifest");
    manifest.status = json.at("status").get<std::string>();
    if (json.contains("info")) manifest.info = json.at("info");
    for (const auto& f : json.at("files")) {
      ResultFileEntry entry;
      entry.path = f.at("path").get<std::string>();
      entry.size = f.at("size").get<uintmax_t>();
      entry.sha256 = f.at("sha256").get<std::string>();
      if (entry.path.empty() || entry.path[0] == '/' || entry.path.find("..") != std::string::npos)
        throw Error(path.string() + ": file path '" + entry.path + "' leaves the folder");
      manifest.files.push_back(std::move(entry));
    }
  } catch (const nlohmann::json::exception& e) {
    throw Error(path.string() + ": malformed manifest (" + e.what() + ")");
  }
  if (manifest.status != "complete" && manifest.status != "interrupted")
    throw Error(path.string() + ": unknown status '" + manifest.status + "'");
  return manifest;
}

namespace {

void VerifyEntry(const fs::path& out, const ResultFileEntry& f) {
  const fs::path path = out / f.path;
  const std::string advice =
      " (changed after the run wrote it, or the run was cut off while committing; rerun it)";
  std::error_code ec;
  RejectNonRegularFile(path);
  if (!fs::is_regular_file(path, ec))
    throw Error(path.string() + ": missing from the result set that manifest.json describes" +
                advice);
  if (fs::file_size(path, ec) != f.size || Sha256OfFile(path) != f.sha256)
    throw Error(path.string() + ": differs from the result set that manifest.json describes" +
                advice);
}

// A reader that finds a commit cut off by a crash finishes it, under the writers' lock, so
// that it reads the complete new set; while a live run holds the lock it refuses.
void FinishCutOffCommitForReader(const fs::path& out) {
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(out / kJournalName, ec))) return;
  const int fd = ::open(out.c_str(), O_DIRECTORY | O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw Error("cannot open " + out.string() + ": " + ErrnoText());
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    ::close(fd);
    throw Error(out.string() +
                ": a run is committing its results into this folder; read them "
                "when it has ended");
  }
  try {
    FinishCutOffCommit(out);
  } catch (const IoError& e) {
    ::close(fd);
    throw Error(std::string(e.what()) + " (a run's commit into " + out.string() +
                " was cut off; rerun sdoslam into it, with write access, to finish it)");
  }
  ::close(fd);
}

[[noreturn]] void ThrowNoManifest(const fs::path& out) {
  if (!StagingFolders(out).empty()) {
    throw Error(out.string() +
                ": holds no complete results: a run into this folder was cut off before it "
                "wrote them (rerun it)");
  }
  throw Error(out.string() + ": not an sdoslam result folder (no " + kManifestName +
              "; results written before version 0.2 have none: rerun)");
}

}  // namespace

ResultManifest VerifyResultSet(const fs::path& out) {
  if (!fs::is_directory(out)) throw Error(out.string() + ": no such folder");
  FinishCutOffCommitForReader(out);
  if (!fs::exists(out / kManifestName)) ThrowNoManifest(out);
  ResultManifest manifest = ReadResultManifest(out);
  for (const ResultFileEntry& f : manifest.files) VerifyEntry(out, f);
  return manifest;
}

std::optional<ResultManifest> VerifyResultFile(const fs::path& file) {
  const fs::path folder = file.has_parent_path() ? file.parent_path() : fs::path(".");
  FinishCutOffCommitForReader(folder);
  if (!fs::exists(folder / kManifestName)) {
    if (!StagingFolders(folder).empty()) ThrowNoManifest(folder);
    return std::nullopt;  // a file from another tool
  }
  ResultManifest manifest = ReadResultManifest(folder);
  const ResultFileEntry* entry = manifest.Find(file.filename().string());
  if (!entry) return std::nullopt;  // the user's own file beside a result set
  VerifyEntry(folder, *entry);
  return manifest;
}

}  // namespace sdoslam
