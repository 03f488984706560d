// What the event streams (GET /api/v1/events) wait on: the newest event the job store has
// recorded, heard through its listener, rung to every stream waiting for one; and how many
// streams are open, since each holds one of the server's threads. Thread-safe.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>

#include "coordinator/jobs/job_store.h"

namespace tcfarm::http {

class EventBell {
 public:
  // Listens to the store from now on; the store must outlive the bell.
  EventBell(JobStore& store, size_t maxStreams);
  ~EventBell();  // stops listening
  EventBell(const EventBell&) = delete;
  EventBell& operator=(const EventBell&) = delete;

  // The newest event's seq: the store's last when the bell was made, or a newer one heard.
  uint64_t Heard() const;
  // Waits until an event after `seq` is heard, the deadline passes or Stop; false once
  // stopped.
  bool Await(uint64_t seq, std::chrono::steady_clock::time_point deadline);
  // Wakes every waiter for good: the server stops. Safe to call twice.
  void Stop();

  // Counts a stream in; false (counting nothing) when maxStreams are open already.
  bool OpenStream();
  void CloseStream() { --openStreams_; }
  size_t maxStreams() const { return maxStreams_; }

 private:
  JobStore& store_;
  const size_t maxStreams_;
  uint64_t listener_ = 0;
  mutable std::mutex mutex_;
  std::condition_variable rung_;
  uint64_t heard_ = 0;
  bool stopping_ = false;
  std::atomic<size_t> openStreams_{0};
};

}  // namespace tcfarm::http
