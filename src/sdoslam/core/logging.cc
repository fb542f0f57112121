#include "sdoslam/core/logging.h"

#include <spdlog/spdlog.h>

#include "sdoslam/core/error.h"

namespace sdoslam {

void SetLogLevel(const std::string& level_name) {
  static const std::pair<const char*, spdlog::level::level_enum> kLevels[] = {
      {"trace", spdlog::level::trace}, {"debug", spdlog::level::debug},
      {"info", spdlog::level::info},   {"warn", spdlog::level::warn},
      {"error", spdlog::level::err},   {"critical", spdlog::level::critical},
      {"off", spdlog::level::off}};
  for (const auto& [name, level] : kLevels) {
    if (level_name == name) {
      spdlog::set_level(level);
      return;
    }
  }
  throw Error("unknown log level '" + level_name +
              "' (use trace, debug, info, warn, error, critical or off)");
}

}  // namespace sdoslam
