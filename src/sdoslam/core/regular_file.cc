#include "sdoslam/core/regular_file.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <system_error>

#include "sdoslam/core/error.h"

namespace sdoslam {
namespace {

Error NotRegular(const std::filesystem::path& path) {
  return Error(path.string() + ": not a regular file");
}

Error CannotOpen(const std::filesystem::path& path, int error) {
  return Error(path.string() + ": cannot open (" +
               std::error_code(error, std::generic_category()).message() + ")");
}

// A file descriptor, closed on destruction.
class Descriptor {
 public:
  explicit Descriptor(int fd) : fd_(fd) {}
  ~Descriptor() {
    if (fd_ >= 0) close(fd_);
  }
  Descriptor(Descriptor&& other) noexcept : fd_(other.fd_) { other.fd_ = -1; }
  Descriptor(const Descriptor&) = delete;
  Descriptor& operator=(const Descriptor&) = delete;
  int get() const { return fd_; }

 private:
  int fd_;
};

// A missing path (or one below a file, ENOTDIR) is the caller's to name.
bool IsMissing(int error) { return error == ENOENT || error == ENOTDIR; }

// Opens a regular file for reading; nullopt when it does not exist. *size: its size.
std::optional<Descriptor> OpenRegular(const std::filesystem::path& path, uint64_t* size) {
  // stat first: a device is refused without opening it (opening some has effects).
  struct stat info {};
  if (stat(path.c_str(), &info) != 0) {
    if (IsMissing(errno)) return std::nullopt;
    throw CannotOpen(path, errno);
  }
  if (!S_ISREG(info.st_mode)) throw NotRegular(path);
  // O_NONBLOCK: should the path have become a FIFO since the stat, open returns at once instead
  // of waiting for a writer, and fstat below refuses it. (No effect on a regular file's reads.)
  Descriptor fd(open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC));
  if (fd.get() < 0) {
    if (IsMissing(errno)) return std::nullopt;
    if (errno == ENXIO) throw NotRegular(path);  // a socket put there since
    throw CannotOpen(path, errno);
  }
  if (fstat(fd.get(), &info) != 0) throw CannotOpen(path, errno);
  if (!S_ISREG(info.st_mode)) throw NotRegular(path);
  *size = static_cast<uint64_t>(info.st_size);
  return fd;
}

// Reads up to `limit` bytes from `fd`; fewer at the end of the file. `expected`: the size
// fstat gave, reserved up front.
std::string ReadUpTo(const Descriptor& fd, uint64_t limit, uint64_t expected,
                     const std::filesystem::path& path) {
  std::string bytes;
  bytes.reserve(static_cast<size_t>(std::min(limit, expected)));
  char buffer[1 << 16];
  while (bytes.size() < limit) {
    const size_t want =
        static_cast<size_t>(std::min<uint64_t>(sizeof(buffer), limit - bytes.size()));
    const ssize_t got = read(fd.get(), buffer, want);
    if (got < 0) {
      if (errno == EINTR) continue;
      throw Error(path.string() + ": cannot read (" +
                  std::error_code(errno, std::generic_category()).message() + ")");
    }
    if (got == 0) break;
    bytes.append(buffer, static_cast<size_t>(got));
  }
  return bytes;
}

std::string Mebibytes(uint64_t bytes) {
  return fmt::format("{:.1f} MiB", static_cast<double>(bytes) / (1024.0 * 1024.0));
}

Error TooLarge(const std::filesystem::path& path, uint64_t size, uint64_t max_bytes) {
  return Error(fmt::format("{}: {} bytes ({}), more than the {} this file may have", path.string(),
                           size, Mebibytes(size), Mebibytes(max_bytes)));
}

}  // namespace

void RejectNonRegularFile(const std::filesystem::path& path) {
  struct stat info {};
  if (stat(path.c_str(), &info) == 0 && !S_ISREG(info.st_mode)) throw NotRegular(path);
}

std::optional<std::string> ReadRegularFileIfExists(const std::filesystem::path& path,
                                                   uint64_t max_bytes) {
  uint64_t size = 0;
  const std::optional<Descriptor> fd = OpenRegular(path, &size);
  if (!fd) return std::nullopt;
  if (size > max_bytes) throw TooLarge(path, size, max_bytes);
  // One byte more than allowed: a file that grew past the limit while read is refused too.
  std::string bytes = ReadUpTo(*fd, max_bytes + 1, size, path);
  if (bytes.size() > max_bytes) throw TooLarge(path, bytes.size(), max_bytes);
  return bytes;
}

std::string ReadRegularFile(const std::filesystem::path& path, uint64_t max_bytes) {
  std::optional<std::string> bytes = ReadRegularFileIfExists(path, max_bytes);
  if (!bytes) throw Error(path.string() + ": not found");
  return std::move(*bytes);
}

std::optional<std::string> ReadRegularFileHead(const std::filesystem::path& path, size_t bytes) {
  uint64_t size = 0;
  const std::optional<Descriptor> fd = OpenRegular(path, &size);
  if (!fd) return std::nullopt;
  return ReadUpTo(*fd, bytes, size, path);
}

}  // namespace sdoslam
