#pragma once

#include "sdoslam/core/error.h"

namespace sdoslam {

// SIGINT / SIGTERM for long runs. While an InterruptHandler lives, the first signal only sets a
// flag that the run loop polls (it finishes the frame in hand and commits what it has); a second
// signal ends the process at once with 128 + signal, leaving the last committed results as they
// were. The destructor restores the earlier handlers. One at a time per process.
class InterruptHandler {
 public:
  // `first_signal_message`: what the first signal prints (a string literal: the handler reads
  // it); by default, that the frame in hand is finished and the results so far are written.
  explicit InterruptHandler(const char* first_signal_message = nullptr);
  ~InterruptHandler();
  InterruptHandler(const InterruptHandler&) = delete;
  InterruptHandler& operator=(const InterruptHandler&) = delete;

  // The first signal received (SIGINT or SIGTERM), or 0.
  static int ReceivedSignal();
  static bool Requested() { return ReceivedSignal() != 0; }
};

// Thrown by a writer that polls InterruptHandler::Requested() and stops (synth): the command
// ends with 130 or 143 once the writer has removed what it staged.
class Interrupted : public Error {
 public:
  Interrupted() : Error("interrupted") {}
};

// While in scope, the abort of a second signal waits until the scope ends: for the short commit
// of a result set, which must not be cut in half. (Not a signal mask: a mask is per thread, and
// OpenCV's and TBB's idle workers would still take the signal.)
class AbortDeferral {
 public:
  AbortDeferral();
  ~AbortDeferral();
  AbortDeferral(const AbortDeferral&) = delete;
  AbortDeferral& operator=(const AbortDeferral&) = delete;
};

}  // namespace sdoslam
