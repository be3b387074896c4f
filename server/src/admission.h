// Admission of planning work: a fixed number of slots (one per core by default) and a bounded
// queue in front of them, so that plans never occupy every request thread and a burst beyond the
// queue is refused at once (429 with Retry-After) instead of piling up.
#pragma once

#include <condition_variable>
#include <functional>
#include <mutex>

#include "npfkct/solver/status.h"

namespace npfkct::server {

/// Planning slots and their queue. Thread-safe.
class Admission {
 public:
  /// `slots` plans at once, at most `queue` more waiting.
  Admission(int slots, int queue) : slots_(slots), queue_(queue) {}

  /// A held slot; released when destroyed.
  class Ticket {
   public:
    Ticket() = default;
    explicit Ticket(Admission* a) : admission_(a) {}
    Ticket(Ticket&& o) noexcept : admission_(o.admission_) { o.admission_ = nullptr; }
    Ticket& operator=(Ticket&& o) noexcept;
    Ticket(const Ticket&) = delete;
    Ticket& operator=(const Ticket&) = delete;
    ~Ticket();

   private:
    Admission* admission_ = nullptr;
  };

  /// Takes a slot, waiting in the queue while none is free. RESOURCE_EXHAUSTED when the queue is
  /// full; CANCELLED when `give_up` (polled every 10 ms while waiting: the client left, the
  /// session was deleted, the server stops) returns true first.
  StatusOr<Ticket> Enter(const std::function<bool()>& give_up);

  int running() const;
  int waiting() const;
  int slots() const { return slots_; }
  int queue() const { return queue_; }

 private:
  void Release();

  const int slots_;
  const int queue_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  int running_ = 0;
  int waiting_ = 0;
};

}  // namespace npfkct::server
