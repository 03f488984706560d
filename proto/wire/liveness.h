// Heartbeat liveness on both ends of the wire (zguide's "paranoid pirate" pattern):
// any message from a peer proves it alive; silence longer than the timeout means dead;
// a worker that lost its coordinator reconnects with exponential back-off.
// Time comes from a Clock so that tests advance it instead of sleeping.
#pragma once

#include <algorithm>
#include <chrono>

namespace tcfarm {

using SteadyTime = std::chrono::steady_clock::time_point;
using Milliseconds = std::chrono::milliseconds;

class Clock {
 public:
  virtual ~Clock() = default;
  virtual SteadyTime Now() const = 0;
};

class SystemClock : public Clock {
 public:
  SteadyTime Now() const override { return std::chrono::steady_clock::now(); }
};

// A clock that moves only when told to.
class FakeClock : public Clock {
 public:
  SteadyTime Now() const override { return now_; }
  void Advance(Milliseconds by) { now_ += by; }

 private:
  SteadyTime now_{};
};

struct HeartbeatPolicy {
  // Idle peers say HEARTBEAT this often, so silence means trouble, not idleness.
  Milliseconds interval{1000};
  // Five missed heartbeats: long enough to ride out a busy moment, short enough that a
  // dead worker's pixels are requeued within seconds.
  Milliseconds timeout{5000};
  Milliseconds backoffInitial{500};
  Milliseconds backoffMax{8000};

  // Another timeout, with heartbeats kept at least five to it, as by default.
  void SetTimeout(Milliseconds silence) {
    timeout = silence;
    interval = std::min(interval, silence / 5);
  }
};

// What one end knows about the other.
class PeerLiveness {
 public:
  PeerLiveness(const HeartbeatPolicy& policy, SteadyTime now)
      : policy_(policy), lastHeard_(now), lastSent_(now) {}

  void OnHeard(SteadyTime now) { lastHeard_ = now; }
  void OnSent(SteadyTime now) { lastSent_ = now; }
  bool ShouldSendHeartbeat(SteadyTime now) const { return now - lastSent_ >= policy_.interval; }
  bool IsDead(SteadyTime now) const { return now - lastHeard_ >= policy_.timeout; }
  SteadyTime lastHeard() const { return lastHeard_; }

 private:
  HeartbeatPolicy policy_;
  SteadyTime lastHeard_;
  SteadyTime lastSent_;
};

// Reconnect delays: initial, doubling, capped; Reset after a successful exchange.
class Backoff {
 public:
  explicit Backoff(const HeartbeatPolicy& policy)
      : initial_(policy.backoffInitial), max_(policy.backoffMax), next_(initial_) {}
  Milliseconds Next() {
    Milliseconds delay = next_;
    next_ = std::min(max_, next_ * 2);
    return delay;
  }
  void Reset() { next_ = initial_; }

 private:
  Milliseconds initial_, max_, next_;
};

}  // namespace tcfarm
