#pragma once

namespace sdoslam {

// SIGINT / SIGTERM for long runs. While an InterruptHandler lives, the first signal only sets a
// flag that the run loop polls (it finishes the frame in hand and commits what it has); a second
// signal ends the process at once with 128 + signal, leaving the last committed results as they
// were. The destructor restores the earlier handlers. One at a time per process.
class InterruptHandler {
 public:
  InterruptHandler();
  ~InterruptHandler();
  InterruptHandler(const InterruptHandler&) = delete;
  InterruptHandler& operator=(const InterruptHandler&) = delete;

  // The first signal received (SIGINT or SIGTERM), or 0.
  static int ReceivedSignal();
  static bool Requested() { return ReceivedSignal() != 0; }
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
