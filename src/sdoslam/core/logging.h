#pragma once

#include <string>

namespace sdoslam {

// Sets spdlog's global level from a name: trace, debug, info, warn, error, critical, off.
// Throws Error for any other name, listing the valid ones.
void SetLogLevel(const std::string& level_name);

}  // namespace sdoslam
