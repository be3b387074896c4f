// Planning admission: slots, a bounded queue, refusal when full, giving up while waiting.
#include "admission.h"

#include <gtest/gtest.h>

#include <atomic>
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

}  // namespace
}  // namespace npfkct::server
