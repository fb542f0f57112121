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
#include <memory>
#include <set>
#include <system_error>

#include "sdoslam/core/error.h"
#include "sdoslam/core/interrupt.h"

namespace sdoslam {
namespace fs = std::filesystem;
namespace {

constexpr char kStagingPrefix[] = ".sdoslam-staging-";
constexpr char kFormat[] = "sdoslam result set";
constexpr int kFormatVersion = 1;

// Result names that sets written before manifests existed may hold: a rerun removes them too.
const std::set<std::string>& LegacyTopLevelNames() {
  static const std::set<std::string> names = {"CameraTrajectory.txt", "KeyFrameTrajectory.txt",
                                              "frames.csv", "config.yaml", "features.csv"};
  return names;
}
constexpr std::array<const char*, 2> kResultFolders = {"masks", "overlays"};

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

// Flushes a file or folder to disk; throws IoError.
void Fsync(const fs::path& path, bool directory) {
  const int fd = ::open(path.c_str(), (directory ? O_DIRECTORY : 0) | O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw IoError("cannot open " + path.string() + " to sync it: " + ErrnoText());
  const int rc = ::fsync(fd);
  const int saved = errno;
  ::close(fd);
  if (rc != 0) throw IoError("cannot sync " + path.string() + ": " + std::strerror(saved));
}

// syncfs(2) flushes every file of the staging folder's file system in one call; fsync of
// thousands of masks one by one would cost seconds.
void SyncFileSystemOf(const fs::path& path) {
  const int fd = ::open(path.c_str(), O_DIRECTORY | O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw IoError("cannot open " + path.string() + " to sync it: " + ErrnoText());
  const int rc = ::syncfs(fd);
  const int saved = errno;
  ::close(fd);
  if (rc != 0) throw IoError("cannot sync " + path.string() + ": " + std::strerror(saved));
}

void Rename(const fs::path& from, const fs::path& to) {
  std::error_code ec;
  fs::rename(from, to, ec);
  // The message comes from this rename's own error code, not from errno of a later call.
  if (ec)
    throw IoError("cannot move " + from.string() + " to " + to.string() + ": " + ec.message());
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

std::optional<ResultManifest> TryReadManifest(const fs::path& out) {
  const fs::path path = out / kManifestName;
  if (!fs::exists(path)) return std::nullopt;
  return ReadResultManifest(out);
}

}  // namespace

const ResultFileEntry* ResultManifest::Find(const std::string& relative_path) const {
  for (const ResultFileEntry& f : files)
    if (f.path == relative_path) return &f;
  return nullptr;
}

std::string Sha256OfFile(const fs::path& path) {
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
  if (fs::exists(out_, ec) && !fs::is_directory(out_, ec))
    throw IoError(out_.string() + ": --out names a file, not a folder");
  if (!fs::exists(out_, ec)) {
    fs::create_directories(out_, ec);
    if (ec) throw IoError("cannot create the output folder " + out_.string() + ": " + ec.message());
    created_out_ = true;
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
  // Holding the lock, every staging folder here is from a run that was cut off.
  for (const fs::path& stale : StagingFolders(out_)) fs::remove_all(stale, ec);

  staging_ = out_ / (std::string(kStagingPrefix) + std::to_string(::getpid()));
  fs::create_directory(staging_, ec);
  if (ec) throw IoError("cannot create " + staging_.string() + ": " + ec.message());
}

ResultSetWriter::~ResultSetWriter() {
  std::error_code ec;
  if (!committed_ && !staging_.empty()) fs::remove_all(staging_, ec);
  if (lock_fd_ >= 0) ::close(lock_fd_);
  if (created_out_ && fs::is_empty(out_, ec)) fs::remove(out_, ec);
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

  std::optional<ResultManifest> old;
  try {
    old = TryReadManifest(out_);
  } catch (const Error&) {
    // A damaged old manifest names nothing reliable; the legacy names below still go.
  }

  // From here on only renames and removals: a second interrupt waits until they are done.
  AbortDeferral defer_abort;
  fs::remove(out_ / kManifestName, ec);  // the old set is no longer vouched for
  std::set<std::string> fresh;
  for (const ResultFileEntry& f : manifest.files) {
    fresh.insert(f.path);
    const fs::path target = out_ / f.path;
    fs::create_directories(target.parent_path(), ec);
    Rename(staging_ / f.path, target);
  }
  std::set<std::string> stale;
  if (old) {
    for (const ResultFileEntry& f : old->files) stale.insert(f.path);
  }
  for (const std::string& name : LegacyTopLevelNames()) stale.insert(name);
  for (const char* folder : kResultFolders) {
    for (const auto& entry : fs::directory_iterator(out_ / folder, ec)) {
      if (entry.is_regular_file(ec))
        stale.insert(fs::relative(entry.path(), out_).generic_string());
    }
  }
  for (const std::string& path : stale) {
    if (!fresh.count(path)) fs::remove(out_ / path, ec);
  }
  for (const char* folder : kResultFolders) {
    if (fs::is_directory(out_ / folder, ec) && fs::is_empty(out_ / folder, ec))
      fs::remove(out_ / folder, ec);
  }
  Rename(staging_ / kManifestName, out_ / kManifestName);
  Fsync(out_, /*directory=*/true);
  committed_ = true;
  fs::remove_all(staging_, ec);
  return manifest;
}

ResultManifest ReadResultManifest(const fs::path& out) {
  const fs::path path = out / kManifestName;
  std::ifstream in(path);
  if (!in) throw Error(path.string() + ": cannot open");
  nlohmann::json json;
  try {
    json = nlohmann::json::parse(in);
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
  if (!fs::is_regular_file(path, ec))
    throw Error(path.string() + ": missing from the result set that manifest.json describes" +
                advice);
  if (fs::file_size(path, ec) != f.size || Sha256OfFile(path) != f.sha256)
    throw Error(path.string() + ": differs from the result set that manifest.json describes" +
                advice);
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
  if (!fs::exists(out / kManifestName)) ThrowNoManifest(out);
  ResultManifest manifest = ReadResultManifest(out);
  for (const ResultFileEntry& f : manifest.files) VerifyEntry(out, f);
  return manifest;
}

std::optional<ResultManifest> VerifyResultFile(const fs::path& file) {
  const fs::path folder = file.has_parent_path() ? file.parent_path() : fs::path(".");
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
