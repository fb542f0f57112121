#pragma once

// The exit codes of the `sdoslam` command, one table (docs/usage.md's "Exit codes" mirrors it and
// cli_test walks it).
namespace sdoslam {

enum ExitCode : int {
  kExitOk = 0,
  kExitBadInput = 1,       // a file, value or option is wrong; the message names it
  kExitUsage = 2,          // the command line itself: unknown option, missing argument
  kExitInternal = 3,       // a bug: please report it with the message
  kExitIo = 4,             // results cannot be written: --out unwritable, disk full, rename failed
  kExitInterrupted = 130,  // SIGINT (128 + 2): the results so far were written, marked so
  kExitTerminated = 143,   // SIGTERM (128 + 15): likewise
};

// Thrown by a command that finished its work but must end with a code other than 0 (an
// interrupted run). Not a std::exception: nothing on the way mistakes it for an error.
struct ExitRequest {
  int code;
};

}  // namespace sdoslam
