#pragma once

#include <cstddef>
#include <utility>
#include <vector>

namespace sdoslam {

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
