#include "sdoslam/core/bounded_queue.h"

#include <gtest/gtest.h>

#include <atomic>
#include <memory>
#include <thread>
#include <vector>

namespace sdoslam {
namespace {

TEST(BoundedQueue, DeliversEveryItemInOrderAcrossThreads) {
  BoundedQueue<int> queue(2);
  constexpr int kItems = 10000;
  std::thread producer([&] {
    for (int i = 0; i < kItems; ++i) ASSERT_TRUE(queue.Push(i));
    queue.Close();
  });
  std::vector<int> received;
  while (std::optional<int> item = queue.Pop()) received.push_back(*item);
  producer.join();
  ASSERT_EQ(received.size(), static_cast<size_t>(kItems));
  for (int i = 0; i < kItems; ++i) ASSERT_EQ(received[static_cast<size_t>(i)], i);
}

TEST(BoundedQueue, PushWaitsWhileFullAndNeverHoldsMoreThanItsCapacity) {
  BoundedQueue<int> queue(2);
  std::atomic<int> pushed{0};
  std::thread producer([&] {
    for (int i = 0; i < 5; ++i) {
      queue.Push(i);
      ++pushed;
    }
  });
  // The producer can get two items in and then waits for the third until one is taken.
  while (pushed.load() < 2) std::this_thread::yield();
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(pushed.load(), 2);
  EXPECT_EQ(*queue.Pop(), 0);
  // Taking one makes room for exactly one more (waited for without a fixed sleep: the machine
  // may be loaded).
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (pushed.load() < 3 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(pushed.load(), 3);
  for (int i = 1; i < 5; ++i) EXPECT_EQ(*queue.Pop(), i);
  producer.join();
}

TEST(BoundedQueue, CloseLetsTheConsumerDrainThenEnds) {
  BoundedQueue<std::unique_ptr<int>> queue(3);  // move-only items
  ASSERT_TRUE(queue.Push(std::make_unique<int>(7)));
  ASSERT_TRUE(queue.Push(std::make_unique<int>(8)));
  queue.Close();
  EXPECT_FALSE(queue.Push(std::make_unique<int>(9)));
  EXPECT_EQ(**queue.Pop(), 7);
  EXPECT_EQ(**queue.Pop(), 8);
  EXPECT_FALSE(queue.Pop().has_value());
  EXPECT_FALSE(queue.Pop().has_value());  // and stays ended
}

TEST(BoundedQueue, CloseWakesAProducerWaitingOnAFullQueue) {
  BoundedQueue<int> queue(1);
  ASSERT_TRUE(queue.Push(1));
  std::atomic<int> result{-1};
  std::thread producer([&] { result = queue.Push(2) ? 1 : 0; });  // waits: the queue is full
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(result.load(), -1);
  queue.Close();
  producer.join();
  EXPECT_EQ(result.load(), 0);
  EXPECT_EQ(*queue.Pop(), 1);  // what was queued before the close is still delivered
}

TEST(BoundedQueue, CloseWakesAConsumerWaitingOnAnEmptyQueue) {
  BoundedQueue<int> queue(1);
  std::atomic<bool> ended{false};
  std::thread consumer([&] { ended = !queue.Pop().has_value(); });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  queue.Close();
  consumer.join();
  EXPECT_TRUE(ended.load());
}

// What SLAM's threads read off the queue: an item waits, is under way, is done.
TEST(BoundedQueue, TellsWhatWaitsWhatIsUnderWayAndWhenItIsDone) {
  BoundedQueue<int> queue;  // no bound
  const auto under_way = [](const auto& view) { return view.under_way.value_or(-1); };
  const auto waiting = [](const auto& view) { return view.waiting.size(); };
  EXPECT_FALSE(queue.waiting());
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(queue.Push(i));
  EXPECT_TRUE(queue.waiting());
  EXPECT_EQ(queue.Inspect(waiting), 3u);
  EXPECT_FALSE(queue.Inspect([](const auto& view) { return view.busy; }));
  EXPECT_EQ(*queue.Pop(), 0);
  EXPECT_EQ(queue.Inspect(under_way), 0);
  EXPECT_TRUE(queue.Inspect([](const auto& view) { return view.busy; }));
  EXPECT_TRUE(queue.waiting());  // 1 and 2 still wait
  queue.Done();
  EXPECT_EQ(queue.Inspect(under_way), -1);
  EXPECT_EQ(*queue.Pop(), 1);
  EXPECT_EQ(*queue.Pop(), 2);
  EXPECT_FALSE(queue.waiting());  // the last one is under way, none waits
  EXPECT_EQ(queue.Inspect(under_way), 2);
}

TEST(BoundedQueue, WaitUntilReturnsWhenTheWorkIsDoneOrTheQueueCloses) {
  BoundedQueue<int> queue;
  ASSERT_TRUE(queue.Push(5));
  std::atomic<int> finished{0};
  std::thread consumer([&] {
    const std::optional<int> item = queue.Pop();
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    finished = *item;
    queue.Done();
  });
  // Waits while 5 waits or is under way: a waiter that only watched the hand-off would return
  // as soon as the consumer took it.
  queue.WaitUntil([](const auto& view) { return view.waiting.empty() && !view.busy; });
  EXPECT_EQ(finished.load(), 5);
  consumer.join();

  ASSERT_TRUE(queue.Push(6));  // never taken: only closing ends the wait
  std::thread closer([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    queue.Close();
  });
  queue.WaitUntil([](const auto& view) { return view.waiting.empty(); });
  closer.join();
  EXPECT_EQ(queue.Inspect([](const auto& view) { return view.waiting.size(); }), 1u);
}

}  // namespace
}  // namespace sdoslam
