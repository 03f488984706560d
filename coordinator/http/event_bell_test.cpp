// The event streams' bell: rung by each event the job store records, silenced by Stop,
// and counting the streams it lets open.
#include "coordinator/http/event_bell.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <future>
#include <random>

namespace tcfarm::http {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

class EventBellTest : public ::testing::Test {
 protected:
  void SetUp() override {
    folder_ = fs::temp_directory_path() / ("tcfarm_event_bell_" + std::to_string(std::random_device()()));
    fs::create_directories(folder_);
    store_ = std::make_unique<JobStore>(folder_ / "jobs.sqlite");
  }
  void TearDown() override {
    store_.reset();
    fs::remove_all(folder_);
  }
  uint64_t SubmitJob() {
    JobSpec spec;
    spec.sceneJson = R"({"camera":{}})";
    spec.sceneHash = "ab12";
    spec.frameSize = {8, 6};
    return store_->Submit(spec);
  }
  static std::chrono::steady_clock::time_point In(std::chrono::milliseconds wait) {
    return std::chrono::steady_clock::now() + wait;
  }

  fs::path folder_;
  std::unique_ptr<JobStore> store_;
};

TEST_F(EventBellTest, StartsFromTheStoresLastEvent) {
  SubmitJob();
  EventBell bell(*store_, 4);
  EXPECT_EQ(bell.Heard(), store_->LastEventSeq());
  EXPECT_GT(bell.Heard(), 0u);
}

TEST_F(EventBellTest, AnEventRecordedWakesAWaiter) {
  EventBell bell(*store_, 4);
  const uint64_t before = bell.Heard();
  std::future<bool> woken = std::async(std::launch::async, [&] { return bell.Await(before, In(10s)); });
  EXPECT_EQ(woken.wait_for(20ms), std::future_status::timeout);
  SubmitJob();
  ASSERT_EQ(woken.wait_for(5s), std::future_status::ready);
  EXPECT_TRUE(woken.get());
  EXPECT_GT(bell.Heard(), before);
}

TEST_F(EventBellTest, AWaitEndsAtItsDeadlineWithoutAnEvent) {
  EventBell bell(*store_, 4);
  EXPECT_TRUE(bell.Await(bell.Heard(), In(10ms)));
}

TEST_F(EventBellTest, StopWakesWaitersForGood) {
  EventBell bell(*store_, 4);
  std::future<bool> woken = std::async(std::launch::async, [&] { return bell.Await(bell.Heard(), In(10s)); });
  bell.Stop();
  ASSERT_EQ(woken.wait_for(5s), std::future_status::ready);
  EXPECT_FALSE(woken.get());
  EXPECT_FALSE(bell.Await(0, In(10s)));  // at once: an event after 0 or not, it has stopped
}

TEST_F(EventBellTest, OpensAtMostMaxStreamsAtOnce) {
  EventBell bell(*store_, 2);
  EXPECT_TRUE(bell.OpenStream());
  EXPECT_TRUE(bell.OpenStream());
  EXPECT_FALSE(bell.OpenStream());
  bell.CloseStream();
  EXPECT_TRUE(bell.OpenStream());
}

}  // namespace
}  // namespace tcfarm::http
