#pragma once

#include <cstddef>

namespace sdoslam {

// The process's resident set size now, in bytes (Linux: /proc/self/statm); 0 where unknown.
size_t ResidentBytes();

// The process's peak resident set size, in bytes, since it started or since the last successful
// ResetPeakResidentBytes() (Linux: VmHWM of /proc/self/status, kept by the kernel, so a peak
// between two samples is not missed); 0 where unknown.
size_t PeakResidentBytes();

// Lowers the kernel's peak to the resident size now, so that PeakResidentBytes() measures one
// stretch of work (a run) inside a longer process (Linux >= 4.0: "5" into /proc/self/clear_refs).
// Returns false where that is not possible: the peak then still covers the whole process.
bool ResetPeakResidentBytes();

// Lets the allocator keep freed image-sized blocks for reuse (glibc: mmap and trim thresholds of
// 16 MiB, mallopt) instead of handing each back to the kernel. Every frame allocates and frees
// images of 0.3–3.7 MB; given back, each is faulted in page by page again on its next use
// (nearly three times the page faults and twice the system time in sdo, the same peak RSS).
// Process-wide: `sdoslam` calls it first thing; a program embedding the library may call it at
// its start. Returns false where the allocator has no such settings.
bool KeepImageBuffersForReuse();

}  // namespace sdoslam
