#include "proto/wire/liveness.h"

#include <gtest/gtest.h>

namespace tcfarm {
namespace {

TEST(LivenessTest, SilenceBeyondTheTimeoutMeansDead) {
  FakeClock clock;
  HeartbeatPolicy policy;
  PeerLiveness peer(policy, clock.Now());
  clock.Advance(Milliseconds(4999));
  EXPECT_FALSE(peer.IsDead(clock.Now()));
  peer.OnHeard(clock.Now());
  clock.Advance(Milliseconds(4999));
  EXPECT_FALSE(peer.IsDead(clock.Now()));
  clock.Advance(Milliseconds(1));
  EXPECT_TRUE(peer.IsDead(clock.Now()));
}

TEST(LivenessTest, HeartbeatsGoOutOnlyWhenIdle) {
  FakeClock clock;
  PeerLiveness peer(HeartbeatPolicy{}, clock.Now());
  clock.Advance(Milliseconds(999));
  EXPECT_FALSE(peer.ShouldSendHeartbeat(clock.Now()));
  clock.Advance(Milliseconds(1));
  EXPECT_TRUE(peer.ShouldSendHeartbeat(clock.Now()));
  peer.OnSent(clock.Now());
  EXPECT_FALSE(peer.ShouldSendHeartbeat(clock.Now()));
}

TEST(LivenessTest, BackoffDoublesToItsCapAndResets) {
  Backoff backoff{HeartbeatPolicy{}};
  EXPECT_EQ(backoff.Next(), Milliseconds(500));
  EXPECT_EQ(backoff.Next(), Milliseconds(1000));
  EXPECT_EQ(backoff.Next(), Milliseconds(2000));
  EXPECT_EQ(backoff.Next(), Milliseconds(4000));
  EXPECT_EQ(backoff.Next(), Milliseconds(8000));
  EXPECT_EQ(backoff.Next(), Milliseconds(8000));
  backoff.Reset();
  EXPECT_EQ(backoff.Next(), Milliseconds(500));
}

// A shorter timeout brings heartbeats closer, five to a timeout; a longer one keeps them.
TEST(HeartbeatPolicyTest, ATimeoutKeepsFiveHeartbeatsWithinIt) {
  HeartbeatPolicy policy;
  policy.SetTimeout(Milliseconds(500));
  EXPECT_EQ(policy.timeout, Milliseconds(500));
  EXPECT_EQ(policy.interval, Milliseconds(100));
  HeartbeatPolicy slow;
  slow.SetTimeout(Milliseconds(60000));
  EXPECT_EQ(slow.interval, HeartbeatPolicy{}.interval);
}

}  // namespace
}  // namespace tcfarm
