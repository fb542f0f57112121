#include "sdoslam/core/interrupt.h"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cstring>

#include "sdoslam/core/error.h"

namespace sdoslam {
namespace {

// Shared between the handler and the program: lock-free atomics are async-signal-safe.
std::atomic<int> g_received{0};        // the first signal
std::atomic<int> g_abort_pending{0};   // a second signal that arrived during a deferral
std::atomic<bool> g_deferring{false};  // an AbortDeferral is alive
static_assert(std::atomic<int>::is_always_lock_free && std::atomic<bool>::is_always_lock_free);
struct sigaction g_old_int, g_old_term;
std::atomic<bool> g_installed{false};
std::atomic<const char*> g_first_message{nullptr};
constexpr char kDefaultFirstMessage[] =
    "\nsdoslam: interrupted; finishing the frame in hand and writing the results so far "
    "(interrupt again to abort without writing)\n";

void WriteStderr(const char* text) {
  // write(2) is async-signal-safe; iostreams and spdlog are not.
  const ssize_t ignored = ::write(STDERR_FILENO, text, std::strlen(text));
  (void)ignored;
}

[[noreturn]] void Abort(int signal) {
  WriteStderr("\nsdoslam: aborted; the output folder keeps its last complete results\n");
  ::_exit(128 + signal);
}

void OnSignal(int signal) {
  int expected = 0;
  if (g_received.compare_exchange_strong(expected, signal)) {
    WriteStderr(g_first_message.load());
    return;
  }
  // Pending first, then the check: whichever of this and ~AbortDeferral looks second aborts.
  g_abort_pending = signal;
  if (!g_deferring.load()) Abort(signal);
}

}  // namespace

InterruptHandler::InterruptHandler(const char* first_signal_message) {
  if (g_installed.exchange(true)) throw Error("InterruptHandler: one at a time per process");
  g_first_message = first_signal_message ? first_signal_message : kDefaultFirstMessage;
  g_received = 0;
  g_abort_pending = 0;
  struct sigaction action {};
  action.sa_handler = OnSignal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = SA_RESTART;  // reads and writes in progress go on
  sigaction(SIGINT, &action, &g_old_int);
  sigaction(SIGTERM, &action, &g_old_term);
}

InterruptHandler::~InterruptHandler() {
  sigaction(SIGINT, &g_old_int, nullptr);
  sigaction(SIGTERM, &g_old_term, nullptr);
  g_installed = false;
}

int InterruptHandler::ReceivedSignal() { return g_received.load(); }

AbortDeferral::AbortDeferral() { g_deferring = true; }

AbortDeferral::~AbortDeferral() {
  g_deferring = false;
  if (const int signal = g_abort_pending.exchange(0); signal != 0) Abort(signal);
}

}  // namespace sdoslam
