#include "sdoslam/core/interrupt.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <functional>

namespace sdoslam {
namespace {

// Runs `body` in a forked child (signals would end the test runner) and returns its wait status.
int InChild(const std::function<int()>& body) {
  const pid_t pid = ::fork();
  if (pid == 0) ::_exit(body());
  int status = 0;
  ::waitpid(pid, &status, 0);
  return status;
}

TEST(InterruptHandler, TheFirstSignalIsOnlyRecordedTheSecondEndsTheProcess) {
  const int status = InChild([] {
    InterruptHandler handler;
    if (InterruptHandler::Requested()) return 10;
    ::raise(SIGTERM);
    if (InterruptHandler::ReceivedSignal() != SIGTERM) return 11;
    ::raise(SIGINT);  // aborts: _exit(128 + SIGINT)
    return 12;
  });
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 128 + SIGINT);
}

TEST(InterruptHandler, ASecondSignalDuringADeferralAbortsOnlyWhenItEnds) {
  int pipe_fds[2];
  ASSERT_EQ(::pipe(pipe_fds), 0);
  const int status = InChild([&] {
    InterruptHandler handler;
    ::raise(SIGINT);
    {
      AbortDeferral commit;
      ::raise(SIGINT);
      // Still alive: the commit finishes.
      const char done = 'c';
      if (::write(pipe_fds[1], &done, 1) != 1) return 20;
    }
    return 21;  // not reached: the deferred abort ends the process here
  });
  char seen = 0;
  ::close(pipe_fds[1]);
  EXPECT_EQ(::read(pipe_fds[0], &seen, 1), 1);
  ::close(pipe_fds[0]);
  EXPECT_EQ(seen, 'c');
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 128 + SIGINT);
}

TEST(InterruptHandler, RestoresTheEarlierHandlersAndAllowsOneAtATime) {
  const int status = InChild([] {
    {
      InterruptHandler handler;
      bool refused = false;
      try {
        InterruptHandler second;
      } catch (const std::exception&) {
        refused = true;
      }
      if (!refused) return 30;
    }
    ::raise(SIGINT);  // default action again: the process dies of it
    return 31;
  });
  ASSERT_TRUE(WIFSIGNALED(status));
  EXPECT_EQ(WTERMSIG(status), SIGINT);
}

}  // namespace
}  // namespace sdoslam
