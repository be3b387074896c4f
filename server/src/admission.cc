#include "admission.h"

#include <chrono>

namespace npfkct::server {

Admission::Ticket& Admission::Ticket::operator=(Ticket&& o) noexcept {
  if (this != &o) {
    if (admission_) admission_->Release();
    admission_ = o.admission_;
    o.admission_ = nullptr;
  }
  return *this;
}

Admission::Ticket::~Ticket() {
  if (admission_) admission_->Release();
}

StatusOr<Admission::Ticket> Admission::Enter(const std::function<bool()>& give_up) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (running_ < slots_ && waiting_ == 0) {
    ++running_;
    return Ticket(this);
  }
  if (waiting_ >= queue_) {
    return ResourceExhaustedError("every planning slot is busy and " + std::to_string(queue_) +
                                  " plans are waiting; retry later");
  }
  ++waiting_;
  while (running_ >= slots_) {
    cv_.wait_for(lock, std::chrono::milliseconds(10));
    if (running_ < slots_) break;
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
  ++running_;
  return Ticket(this);
}

void Admission::Release() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    --running_;
  }
  cv_.notify_one();
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
