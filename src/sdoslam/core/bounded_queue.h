#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <limits>
#include <mutex>
#include <optional>
#include <type_traits>
#include <utility>

namespace sdoslam {

// The one queue of every thread hand-off: a blocking FIFO of at most `capacity` items between a
// stage and the next, with an end of stream. Push waits while the queue is full (an offline run
// never drops a frame); Pop waits while it is empty; both wait on condition variables, never
// spinning. The consumer may also say when it has finished the item it took (Done): a producer
// can then wait for the work, not only the hand-off (WaitUntil), and see whether the consumer
// is idle (Inspect); SLAM's mapping and loop-closing threads use that.
//
// Written here rather than taken from TBB: tbb::concurrent_bounded_queue has no end of stream
// (its abort() throws in every waiting thread and leaves queued items behind), and a stage that
// stops must let the next one drain what was already made.
template <typename T>
class BoundedQueue {
 public:
  // 0: no bound.
  explicit BoundedQueue(size_t capacity = 0)
      : capacity_(capacity > 0 ? capacity : std::numeric_limits<size_t>::max()) {}

  // Waits for room, then appends. Returns false (and drops `item`) once the queue is closed.
  bool Push(T item) {
    std::unique_lock<std::mutex> lock(mutex_);
    not_full_.wait(lock, [this] { return closed_ || items_.size() < capacity_; });
    if (closed_) return false;
    items_.push_back(std::move(item));
    waiting_ = true;
    lock.unlock();
    not_empty_.notify_one();
    return true;
  }

  // Waits for an item and takes it: it is under way until Done() or the next Pop. Returns
  // nullopt when the queue is closed and every item was taken.
  std::optional<T> Pop() {
    std::unique_lock<std::mutex> lock(mutex_);
    not_empty_.wait(lock, [this] { return closed_ || !items_.empty(); });
    if (items_.empty()) return std::nullopt;
    std::optional<T> item(std::move(items_.front()));
    items_.pop_front();
    busy_ = true;
    // Kept for View only where a copy is cheap (a pointer, an index): frames are not copied.
    if constexpr (std::is_trivially_copyable_v<T>) under_way_ = *item;
    waiting_ = !items_.empty();
    lock.unlock();
    not_full_.notify_one();
    return item;
  }

  // The item taken last is finished: wakes WaitUntil.
  void Done() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      busy_ = false;
      under_way_.reset();
    }
    work_done_.notify_all();
  }

  // The end of stream: later pushes fail, waiting pushers return false, poppers take what is
  // left and then get nullopt, WaitUntil returns. Idempotent.
  void Close() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      closed_ = true;
    }
    not_full_.notify_all();
    not_empty_.notify_all();
    work_done_.notify_all();
  }

  // The queue as one consistent picture: the items waiting (oldest first), whether one is under
  // way, and (for trivially copyable T) which.
  struct View {
    const std::deque<T>& waiting;
    bool busy;
    const std::optional<T>& under_way;
  };
  // `look(View)`'s result, under the queue's lock.
  template <class Look>
  auto Inspect(Look&& look) const {
    std::lock_guard<std::mutex> lock(mutex_);
    return look(View{items_, busy_, under_way_});
  }
  // Waits until `done(View)` holds, re-checked whenever an item is finished; returns at once
  // once the queue is closed.
  template <class Condition>
  void WaitUntil(Condition&& done) {
    std::unique_lock<std::mutex> lock(mutex_);
    work_done_.wait(lock, [&] { return closed_ || done(View{items_, busy_, under_way_}); });
  }

  // Raised while an item waits to be taken (not counting the one under way): a consumer can poll
  // it without the lock, e.g. to cut its current work short.
  const std::atomic<bool>& waiting() const { return waiting_; }

  size_t capacity() const { return capacity_; }

 private:
  const size_t capacity_;
  mutable std::mutex mutex_;
  std::condition_variable not_full_, not_empty_, work_done_;
  std::deque<T> items_;
  std::optional<T> under_way_;
  std::atomic<bool> waiting_{false};
  bool busy_ = false;
  bool closed_ = false;
};

}  // namespace sdoslam
