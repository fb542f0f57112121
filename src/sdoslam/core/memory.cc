#include "sdoslam/core/memory.h"

#include <unistd.h>

#include <fstream>

namespace sdoslam {

size_t ResidentBytes() {
  std::ifstream statm("/proc/self/statm");
  size_t total_pages = 0, resident_pages = 0;
  if (!(statm >> total_pages >> resident_pages)) return 0;
  const long page = sysconf(_SC_PAGESIZE);
  return page > 0 ? resident_pages * static_cast<size_t>(page) : 0;
}

}  // namespace sdoslam
