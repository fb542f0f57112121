#pragma once

#include <cstddef>
#include <utility>
#include <vector>

namespace sdoslam {

// Timestamps are seconds (TUM: since 1970, about 1.3e9; synthetic sequences: from 0). Beyond
// this (the year 2286) a value is not seconds but nanoseconds or garbage: a last rgb.txt line
// at 1e308 was dropped for lack of a depth image near it instead of named.
inline constexpr double kMaxAbsTimestamp = 1e10;

// Pairs of indices (i into `first`, j into `second`) whose timestamps differ by less than
// `max_difference` seconds (after adding `offset` to the second), chosen as the TUM benchmark's
// associate tool does: all candidate pairs sorted by time difference, taken greedily so that
// each element is used at most once. Returned sorted by i. Ties are broken by (i, j), so the
// result never depends on anything but the inputs.
std::vector<std::pair<size_t, size_t>> AssociateTimestamps(const std::vector<double>& first,
                                                           const std::vector<double>& second,
                                                           double max_difference,
                                                           double offset = 0.0);

}  // namespace sdoslam
