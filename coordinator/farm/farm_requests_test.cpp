// The farm loop's mailbox: what other threads ask waits for the loop, and a release
// waits for the loop to settle it.
#include "coordinator/farm/farm_requests.h"

#include <gtest/gtest.h>

#include <chrono>
#include <future>

namespace tcfarm {
namespace {

using namespace std::chrono_literals;

TEST(FarmRequestsTest, TakeHandsOverWhatWasAskedOnce) {
  FarmRequests requests;
  requests.Cancel(3);
  requests.SetPriority(4, 10);
  requests.SetPriority(4, -5);  // the latest wins
  requests.LiftBan("key-a");
  FarmRequests::Batch asked = requests.Take();
  EXPECT_EQ(asked.cancels, (std::set<uint64_t>{3}));
  EXPECT_EQ(asked.priorities, (std::map<uint64_t, int>{{4, -5}}));
  EXPECT_EQ(asked.liftedBans, (std::vector<std::string>{"key-a"}));
  FarmRequests::Batch again = requests.Take();
  EXPECT_TRUE(again.cancels.empty());
  EXPECT_TRUE(again.priorities.empty());
  EXPECT_TRUE(again.liftedBans.empty());
}

TEST(FarmRequestsTest, ReleaseReturnsOnceTheLoopSettlesIt) {
  FarmRequests requests;
  std::future<bool> released = std::async(std::launch::async, [&] { return requests.Release(7); });
  FarmRequests::Batch asked;
  while (asked.releases.empty()) asked.releases = requests.Take().releases;
  ASSERT_EQ(asked.releases.size(), 1u);
  EXPECT_EQ(asked.releases[0].first, 7u);
  EXPECT_EQ(released.wait_for(20ms), std::future_status::timeout);  // waits for the loop
  requests.Settle(asked.releases, {});
  EXPECT_TRUE(released.get());
}

TEST(FarmRequestsTest, AnUnreadReleaseIsAskedAgainWithItsCancel) {
  FarmRequests requests;
  std::future<bool> released = std::async(std::launch::async, [&] { return requests.Release(7); });
  std::vector<FarmRequests::ReleaseTicket> releases;
  while (releases.empty()) releases = requests.Take().releases;
  requests.Settle(releases, {7});
  EXPECT_EQ(released.wait_for(20ms), std::future_status::timeout);
  FarmRequests::Batch again = requests.Take();
  EXPECT_EQ(again.releases, releases);
  EXPECT_EQ(again.cancels, (std::set<uint64_t>{7}));
  requests.Settle(again.releases, {});
  EXPECT_TRUE(released.get());
}

TEST(FarmRequestsTest, StopAnswersWaitingAndLaterReleasesWithFalse) {
  FarmRequests requests;
  std::future<bool> released = std::async(std::launch::async, [&] { return requests.Release(7); });
  while (requests.Take().releases.empty()) {
  }
  requests.Stop();
  EXPECT_FALSE(released.get());
  EXPECT_FALSE(requests.Release(8));
}

TEST(FarmRequestsTest, SnapshotIsTheLastPublished) {
  FarmRequests requests;
  FarmSnapshot snapshot;
  snapshot.queuedTasks = 5;
  requests.Publish(snapshot);
  EXPECT_EQ(requests.Snapshot().queuedTasks, 5u);
}

}  // namespace
}  // namespace tcfarm
