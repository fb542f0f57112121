#pragma once

#include <chrono>
#include <mutex>

namespace sdoslam {

// Lets go of the lock on the map around work that touches nothing of the map (Lucas–Kanade of
// the consistency check, the static world's motion, the pose solves), so that local mapping is
// not held up by it, and counts the time spent taking the lock back. The Tracker owns one and
// hands it to the parts of tracking that do such work.
class MapLockReleaser {
 public:
  // From the start of a frame: `lock` is the lock on the map the caller holds (threaded runs),
  // or nullptr (inline runs): then work runs as is. Clears the wait.
  void Begin(std::unique_lock<std::mutex>* lock) {
    lock_ = lock;
    wait_ms_ = 0;
  }
  // At the frame's end: the lock is the caller's again.
  void End() { lock_ = nullptr; }
  // Milliseconds spent taking the lock back since Begin.
  double wait_ms() const { return wait_ms_; }

  // Runs `work` without the lock when one was given and is held, and takes it back afterwards
  // (also when `work` throws); `work` must touch nothing of the map. Returns what `work` does.
  template <typename Work>
  auto WithoutMapLock(Work&& work) {
    if (lock_ == nullptr || !lock_->owns_lock()) return work();
    struct Relock {
      std::unique_lock<std::mutex>* lock;
      double* wait_ms;
      ~Relock() {
        const auto start = std::chrono::steady_clock::now();
        lock->lock();
        *wait_ms +=
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                .count();
      }
    };
    lock_->unlock();
    Relock relock{lock_, &wait_ms_};
    return work();
  }

 private:
  std::unique_lock<std::mutex>* lock_ = nullptr;
  double wait_ms_ = 0;
};

}  // namespace sdoslam
