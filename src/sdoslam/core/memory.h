#pragma once

#include <cstddef>

namespace sdoslam {

// The process's resident set size now, in bytes (Linux: /proc/self/statm); 0 where unknown.
size_t ResidentBytes();

}  // namespace sdoslam
