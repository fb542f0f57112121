// sdoslam: one command, many subcommands. Library errors (sdoslam::Error) end here as one
// message and exit code 1; command-line mistakes as CLI11's message and its exit code.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <iostream>

#include "sdoslam/apps/bench_command.h"
#include "sdoslam/apps/convert_command.h"
#include "sdoslam/apps/demo_command.h"
#include "sdoslam/apps/eval_command.h"
#include "sdoslam/apps/eval_masks_command.h"
#include "sdoslam/apps/run_command.h"
#include "sdoslam/apps/synth_command.h"
#include "sdoslam/core/error.h"
#include "sdoslam/core/logging.h"

int main(int argc, char** argv) {
  CLI::App app{"sdoslam: visual SLAM for scenes that move (RGB-D, known and unknown objects)"};
  app.require_subcommand(1);
  std::string log_level = "info";
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error, critical, off")
      ->capture_default_str();
  app.parse_complete_callback([&] { sdoslam::SetLogLevel(log_level); });
  sdoslam::AddEvalCommand(app);
  sdoslam::AddDemoCommand(app);
  sdoslam::AddSynthCommand(app);
  sdoslam::AddRunCommand(app);
  sdoslam::AddBenchCommand(app);
  sdoslam::AddEvalMasksCommand(app);
  sdoslam::AddConvertCommand(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const sdoslam::Error& e) {
    std::cerr << "error: " << e.what() << '\n';
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "internal error: " << e.what() << '\n';
    return 3;
  }
  return 0;
}
