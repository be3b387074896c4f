// Admission of planning work: a fixed number of slots (one per core by default) and a bounded
// queue in front of them, so that plans never occupy every request thread and a burst beyond the
// queue is refused at once (429 with Retry-After) instead of piling up.
#pragma once

#include <sched.h>

#include <condition_variable>
#include <functional>
#include <mutex>

#include "npfkct/common/status.h"

namespace npfkct::server {

/// Planning slots and their queue: a plan takes one slot per thread it searches on. Thread-safe.
class Admission {
 public:
  /// `slots` plans at once, at most `queue` more waiting.
  Admission(int slots, int queue) : slots_(slots), queue_(queue) {}

  /// A held slot; released when destroyed.
  class Ticket {
   public:
    Ticket() = default;
    Ticket(Admission* a, int slots) : admission_(a), slots_(slots) {}
    Ticket(Ticket&& o) noexcept : admission_(o.admission_), slots_(o.slots_) {
      o.admission_ = nullptr;
    }
    Ticket& operator=(Ticket&& o) noexcept;
    Ticket(const Ticket&) = delete;
    Ticket& operator=(const Ticket&) = delete;
    ~Ticket();

   private:
    Admission* admission_ = nullptr;
    int slots_ = 0;
  };

  /// Takes `threads` slots (at most all of them), waiting in the queue while too few are free.
  /// RESOURCE_EXHAUSTED when the queue is full; CANCELLED when `give_up` (polled every 10 ms
  /// while waiting: the client left, the session was deleted, the server stops) returns true
  /// first.
  StatusOr<Ticket> Enter(const std::function<bool()>& give_up, int threads = 1);

  /// Slots held.
  int running() const;
  int waiting() const;
  int slots() const { return slots_; }
  int queue() const { return queue_; }

 private:
  void Release(int slots);

  const int slots_;
  const int queue_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  int running_ = 0;
  int waiting_ = 0;
};

// Runs the search loop under SCHED_BATCH: planners keep their fair share of the CPU, but threads
// that wake up to parse a request or send a reply (SCHED_OTHER) preempt them, so that many
// sessions planning on few cores delay each other's responses less. The policy is restored on
// scope exit (an unprivileged thread may switch back to SCHED_OTHER).
class BatchScheduling {
 public:
  BatchScheduling() {
    sched_param p{};
    active_ = sched_setscheduler(0, SCHED_BATCH, &p) == 0;
  }
  ~BatchScheduling() {
    if (!active_) return;
    sched_param p{};
    sched_setscheduler(0, SCHED_OTHER, &p);
  }
  BatchScheduling(const BatchScheduling&) = delete;
  BatchScheduling& operator=(const BatchScheduling&) = delete;

 private:
  bool active_ = false;
};

}  // namespace npfkct::server
