#include "coordinator/http/event_bell.h"

#include <algorithm>

namespace tcfarm::http {

EventBell::EventBell(JobStore& store, size_t maxStreams) : store_(store), maxStreams_(maxStreams) {
  heard_ = store_.LastEventSeq();
  listener_ = store_.AddEventListener([this](const JobEvent& event) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      heard_ = std::max(heard_, event.seq);
    }
    rung_.notify_all();
  });
}

EventBell::~EventBell() { store_.RemoveEventListener(listener_); }

uint64_t EventBell::Heard() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return heard_;
}

bool EventBell::Await(uint64_t seq, std::chrono::steady_clock::time_point deadline) {
  std::unique_lock<std::mutex> lock(mutex_);
  rung_.wait_until(lock, deadline, [&] { return stopping_ || heard_ > seq; });
  return !stopping_;
}

void EventBell::Stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  rung_.notify_all();
}

bool EventBell::OpenStream() {
  if (++openStreams_ > maxStreams_) {
    --openStreams_;
    return false;
  }
  return true;
}

}  // namespace tcfarm::http
