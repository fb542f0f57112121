#include "sdoslam/tracking/map_lock.h"

#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <thread>

namespace sdoslam {
namespace {

TEST(MapLockReleaser, WithoutALockWorkRunsAsIs) {
  MapLockReleaser releaser;
  EXPECT_EQ(releaser.WithoutMapLock([] { return 7; }), 7);
  std::mutex mutex;
  std::unique_lock<std::mutex> not_held(mutex, std::defer_lock);
  releaser.Begin(&not_held);
  bool ran = false;
  releaser.WithoutMapLock([&] { ran = true; });
  EXPECT_TRUE(ran);
  EXPECT_FALSE(not_held.owns_lock());  // not taken either
  EXPECT_EQ(releaser.wait_ms(), 0);
}

TEST(MapLockReleaser, ReleasesTheLockForTheWorkAndTakesItBack) {
  std::mutex mutex;
  std::unique_lock<std::mutex> lock(mutex);
  MapLockReleaser releaser;
  releaser.Begin(&lock);
  bool taken_inside = false;
  const bool held_inside = releaser.WithoutMapLock([&] {
    // Another thread can take the map meanwhile.
    std::thread other([&] {
      taken_inside = mutex.try_lock();
      if (taken_inside) mutex.unlock();
    });
    other.join();
    return lock.owns_lock();
  });
  EXPECT_FALSE(held_inside);
  EXPECT_TRUE(taken_inside);
  EXPECT_TRUE(lock.owns_lock());
  // Also when the work throws.
  EXPECT_THROW(releaser.WithoutMapLock([]() -> int { throw std::runtime_error("work"); }),
               std::runtime_error);
  EXPECT_TRUE(lock.owns_lock());
  releaser.End();
  bool ran = false;
  releaser.WithoutMapLock([&] {
    ran = true;
    EXPECT_TRUE(lock.owns_lock());  // after End the lock stays held
  });
  EXPECT_TRUE(ran);
}

TEST(MapLockReleaser, CountsTheWaitToTakeTheLockBackUntilTheNextBegin) {
  std::mutex mutex;
  std::unique_lock<std::mutex> lock(mutex);
  MapLockReleaser releaser;
  releaser.Begin(&lock);
  std::atomic<bool> taken{false};
  std::thread other;
  releaser.WithoutMapLock([&] {
    if (lock.owns_lock()) return;  // not released: nothing to wait for
    other = std::thread([&] {
      std::lock_guard<std::mutex> hold(mutex);
      taken = true;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    });
    while (!taken) std::this_thread::yield();
  });
  ASSERT_TRUE(other.joinable());
  other.join();
  EXPECT_GE(releaser.wait_ms(), 40.0);
  releaser.End();
  EXPECT_GE(releaser.wait_ms(), 40.0);  // kept for the caller after the frame
  releaser.Begin(&lock);
  EXPECT_EQ(releaser.wait_ms(), 0);
}

}  // namespace
}  // namespace sdoslam
