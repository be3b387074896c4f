#include "admission.h"

#include <algorithm>
#include <chrono>

namespace npfkct::server {

Admission::Ticket& Admission::Ticket::operator=(Ticket&& o) noexcept {
  if (this != &o) {
    if (admission_) admission_->Release(slots_);
    admission_ = o.admission_;
    slots_ = o.slots_;
    o.admission_ = nullptr;
  }
  return *this;
}

Admission::Ticket::~Ticket() {
  if (admission_) admission_->Release(slots_);
}

StatusOr<Admission::Ticket> Admission::Enter(const std::function<bool()>& give_up, int threads) {
  const int need = std::clamp(threads, 1, slots_);
  std::unique_lock<std::mutex> lock(mutex_);
  if (running_ + need <= slots_ && waiting_ == 0) {
    running_ += need;
    return Ticket(this, need);
  }
  if (waiting_ >= queue_) {
    return ResourceExhaustedError("every planning slot is busy and " + std::to_string(queue_) +
                                  " plans are waiting; retry later");
  }
  ++waiting_;
  while (running_ + need > slots_) {
    cv_.wait_for(lock, std::chrono::milliseconds(10));
    if (running_ + need <= slots_) break;
    lock.unlock();
    const bool stop = give_up && give_up();
    lock.lock();
    if (stop) {
      --waiting_;
      cv_.notify_one();
      return CancelledError("gave up waiting for a planning slot");
    }
  }
  --waiting_;
  running_ += need;
  return Ticket(this, need);
}

void Admission::Release(int slots) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    running_ -= slots;
  }
  cv_.notify_all();  // a plan of several threads may free room for several waiting ones
}

int Admission::running() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return running_;
}

int Admission::waiting() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return waiting_;
}

}  // namespace npfkct::server
