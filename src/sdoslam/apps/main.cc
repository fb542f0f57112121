// sdoslam: one command, many subcommands. Every failure ends here as one message and one exit
// code of apps/exit_codes.h: bad input 1, usage 2, internal 3, I/O 4, interrupted 130 / 143.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <filesystem>
#include <iostream>

#include "sdoslam/apps/bench_command.h"
#include "sdoslam/apps/convert_command.h"
#include "sdoslam/apps/demo_command.h"
#include "sdoslam/apps/eval_command.h"
#include "sdoslam/apps/eval_masks_command.h"
#include "sdoslam/apps/eval_objects_command.h"
#include "sdoslam/apps/exit_codes.h"
#include "sdoslam/apps/run_command.h"
#include "sdoslam/apps/synth_command.h"
#include "sdoslam/apps/vocab_command.h"
#include "sdoslam/core/error.h"
#include "sdoslam/core/logging.h"
#include "sdoslam/core/memory.h"

namespace {

// An empty output path is a slip on the command line (--out "$UNSET"), not a folder that cannot
// be written: a usage error (exit 2) instead of the I/O error (4) that creating "" gave.
const CLI::Validator kNotEmpty(
    [](std::string& value) { return value.empty() ? std::string("must not be empty") : ""; }, "",
    "NOT_EMPTY");

// Every command's output option (--out; bench's --work), in subcommands of subcommands too.
void RefuseEmptyOutputs(CLI::App& app) {
  for (CLI::App* command : app.get_subcommands([](CLI::App*) { return true; })) {
    for (const char* name : {"--out", "--work"}) {
      if (CLI::Option* option = command->get_option_no_throw(name)) option->check(kNotEmpty);
    }
    RefuseEmptyOutputs(*command);
  }
}

}  // namespace

int main(int argc, char** argv) {
  sdoslam::KeepImageBuffersForReuse();  // before the first image: see memory.h
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
  sdoslam::AddEvalObjectsCommand(app);
  sdoslam::AddConvertCommand(app);
  sdoslam::AddVocabCommand(app);
  RefuseEmptyOutputs(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {
    return app.exit(e);  // --help
  } catch (const CLI::ParseError& e) {
    app.exit(e);  // prints CLI11's message and the hint to --help
    return sdoslam::kExitUsage;
  } catch (const sdoslam::ExitRequest& e) {
    return e.code;
  } catch (const sdoslam::IoError& e) {
    std::cerr << "error: " << e.what() << '\n';
    return sdoslam::kExitIo;
  } catch (const sdoslam::Error& e) {
    std::cerr << "error: " << e.what() << '\n';
    return sdoslam::kExitBadInput;
  } catch (const std::filesystem::filesystem_error& e) {
    // The file system refused something (permissions, space); its message names the path.
    std::cerr << "error: " << e.what() << '\n';
    return sdoslam::kExitIo;
  } catch (const std::exception& e) {
    std::cerr << "internal error (please report it): " << e.what() << '\n';
    return sdoslam::kExitInternal;
  }
  return sdoslam::kExitOk;
}
