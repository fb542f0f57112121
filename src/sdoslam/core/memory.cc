#include "sdoslam/core/memory.h"

#include <unistd.h>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <fstream>
#include <string>

namespace sdoslam {

size_t ResidentBytes() {
  std::ifstream statm("/proc/self/statm");
  size_t total_pages = 0, resident_pages = 0;
  if (!(statm >> total_pages >> resident_pages)) return 0;
  const long page = sysconf(_SC_PAGESIZE);
  return page > 0 ? resident_pages * static_cast<size_t>(page) : 0;
}

size_t PeakResidentBytes() {
  std::ifstream status("/proc/self/status");
  std::string key;
  while (status >> key) {
    if (key == "VmHWM:") {
      size_t kilobytes = 0;  // the kernel writes "VmHWM:   123456 kB"
      return status >> kilobytes ? kilobytes * 1024 : 0;
    }
    status.ignore(1 << 16, '\n');
  }
  return 0;
}

bool ResetPeakResidentBytes() {
  std::ofstream clear_refs("/proc/self/clear_refs");
  if (!(clear_refs << "5" << std::flush)) return false;
  // Kernels without the reset take the write and leave the peak alone: check that it moved.
  return PeakResidentBytes() <= ResidentBytes() + (1 << 20);
}

bool KeepImageBuffersForReuse() {
#if defined(__GLIBC__)
  // Blocks up to 16 MiB come from the heap, and up to 16 MiB of free heap top stays mapped.
  // (Setting either also stops glibc's own threshold from moving with what is freed.)
  constexpr int kBytes = 16 << 20;
  return mallopt(M_MMAP_THRESHOLD, kBytes) == 1 && mallopt(M_TRIM_THRESHOLD, kBytes) == 1;
#else
  return false;
#endif
}

}  // namespace sdoslam
