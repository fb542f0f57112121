#include "sdoslam/core/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <string>
#include <system_error>

#include "sdoslam/core/error.h"

namespace sdoslam {
namespace {

std::filesystem::path TemporaryPathFor(const std::filesystem::path& path) {
  std::filesystem::path tmp = path;
  // Built by appending: GCC 12 warns (-Wrestrict, a false positive) on `"." + string`.
  std::string name = ".";
  name += path.stem().string();
  name += ".tmp";
  name += std::to_string(::getpid());
  name += path.extension().string();
  tmp.replace_filename(name);
  return tmp;
}

void PrepareParent(const std::filesystem::path& path) {
  const auto parent = path.parent_path();
  if (parent.empty()) return;
  std::error_code ec;
  std::filesystem::create_directories(parent, ec);
  if (ec) throw IoError("cannot create folder " + parent.string() + ": " + ec.message());
}

void Commit(const std::filesystem::path& tmp, const std::filesystem::path& path) {
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    // The rename's own error, read before the clean-up below can overwrite it.
    const std::string why = ec.message();
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw IoError("cannot write " + path.string() + ": " + why);
  }
}

}  // namespace

void WriteFileAtomically(const std::filesystem::path& path,
                         const std::function<void(std::ostream&)>& write) {
  PrepareParent(path);
  const auto tmp = TemporaryPathFor(path);
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw IoError("cannot write " + path.string());
    try {
      write(out);
    } catch (...) {
      out.close();
      std::error_code ec;
      std::filesystem::remove(tmp, ec);
      throw;
    }
    out.flush();
    if (!out) {
      out.close();
      std::error_code ec;
      std::filesystem::remove(tmp, ec);
      throw IoError("cannot write " + path.string() + " (disk full?)");
    }
  }
  Commit(tmp, path);
}

void WriteFileAtomically(const std::filesystem::path& path,
                         const std::function<bool(const std::filesystem::path&)>& write) {
  PrepareParent(path);
  const auto tmp = TemporaryPathFor(path);
  bool ok = false;
  try {
    ok = write(tmp);
  } catch (...) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw;
  }
  if (!ok || !std::filesystem::exists(tmp)) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw IoError("cannot write " + path.string());
  }
  Commit(tmp, path);
}

namespace {

// Opens `path` (with `flags`), runs `sync` (fsync or syncfs) on it; throws IoError naming it.
void SyncThrough(const std::filesystem::path& path, int flags, int (*sync)(int)) {
  const int fd = ::open(path.c_str(), flags | O_RDONLY | O_CLOEXEC);
  if (fd < 0)
    throw IoError("cannot open " + path.string() + " to sync it: " + std::strerror(errno));
  const int rc = sync(fd);
  const int saved = errno;
  ::close(fd);
  if (rc != 0) throw IoError("cannot sync " + path.string() + ": " + std::strerror(saved));
}

}  // namespace

void SyncToDisk(const std::filesystem::path& path) { SyncThrough(path, 0, ::fsync); }

void SyncFileSystemOf(const std::filesystem::path& folder) {
  SyncThrough(folder, O_DIRECTORY, ::syncfs);
}

}  // namespace sdoslam
