// Planning admission: slots, a bounded queue, refusal when full, giving up while waiting.
#include "admission.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>

namespace npfkct::server {
namespace {

TEST(Admission, RunsQueuesThenRefuses) {
  Admission a(1, 1);
  auto first = a.Enter(nullptr);
  ASSERT_TRUE(first.ok());
  EXPECT_EQ(a.running(), 1);
  std::atomic<bool> entered{false};
  std::thread waiter([&] {
    auto t = a.Enter(nullptr);
    EXPECT_TRUE(t.ok());
    entered = true;
  });
  while (a.waiting() == 0) std::this_thread::yield();
  // Slot and queue taken: refused at once.
  auto third = a.Enter(nullptr);
  EXPECT_EQ(third.status().code(), StatusCode::kResourceExhausted);
  EXPECT_FALSE(entered);
  { auto released = std::move(first).value(); }  // the slot frees, the waiter runs
  waiter.join();
  EXPECT_TRUE(entered);
  EXPECT_EQ(a.running(), 0);
  EXPECT_EQ(a.waiting(), 0);
}

TEST(Admission, AWaiterGivesUp) {
  Admission a(1, 4);
  auto held = a.Enter(nullptr);
  ASSERT_TRUE(held.ok());
  std::atomic<bool> gone{false};
  std::thread t([&] {
    auto r = a.Enter([&] { return gone.load(); });
    EXPECT_EQ(r.status().code(), StatusCode::kCancelled);
  });
  while (a.waiting() == 0) std::this_thread::yield();
  gone = true;
  t.join();
  EXPECT_EQ(a.waiting(), 0);
  EXPECT_EQ(a.running(), 1);
}

TEST(Admission, APlanOfSeveralThreadsTakesASlotForEach) {
  // One slot per core: a plan searching on 3 threads of 4 slots leaves room for one more
  // single-threaded plan; a 2-thread plan waits until the 3 come back.
  Admission a(4, 2);
  auto three = a.Enter(nullptr, 3);
  ASSERT_TRUE(three.ok());
  EXPECT_EQ(a.running(), 3);
  auto one = a.Enter(nullptr, 1);
  ASSERT_TRUE(one.ok());
  EXPECT_EQ(a.running(), 4);
  std::atomic<bool> entered{false};
  std::thread two([&] {
    auto t = a.Enter(nullptr, 2);
    EXPECT_TRUE(t.ok());
    EXPECT_EQ(a.running(), 2);
    entered = true;
  });
  while (a.waiting() == 0) std::this_thread::yield();
  { auto released = std::move(one).value(); }  // 1 free: not enough for 2
  std::this_thread::sleep_for(std::chrono::milliseconds(30));
  EXPECT_FALSE(entered);
  { auto released = std::move(three).value(); }
  two.join();
  EXPECT_TRUE(entered);
  EXPECT_EQ(a.running(), 0);
  // More threads than slots take them all, and never wait forever.
  auto all = a.Enter(nullptr, 64);
  ASSERT_TRUE(all.ok());
  EXPECT_EQ(a.running(), 4);
}

}  // namespace
}  // namespace npfkct::server
