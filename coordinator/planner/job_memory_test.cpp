#include "coordinator/planner/job_memory.h"

#include <gtest/gtest.h>

namespace tcfarm {
namespace {

JobMemoryShape Search(int width, int height, int binWidth, int frames, uint64_t pendingFrameBytes = 0) {
  return {width, height, frames, Strategy::kSearch, binWidth, false, pendingFrameBytes};
}

// What a job holds at once grows with bins and bin width and is capped by the job's own
// frames.
TEST(JobMemoryTest, FramesHeldGrowWithBinsAndAreCappedByTheJob) {
  EXPECT_EQ(FramesHeldPerJob(Strategy::kSearch, 10, 4, 60), 4 * 11 + kFarmFramesPerJob);
  EXPECT_EQ(FramesHeldPerJob(Strategy::kSearch, 10, 4, 10), 14);  // a 10-frame job
  EXPECT_EQ(FramesHeldPerJob(Strategy::kBrute, 500, 1, 60), 3 + kFarmFramesPerJob);  // bins of 2
  EXPECT_EQ(FramesHeldPerJob(Strategy::kExact, 60, 4, 60), 4 + kFarmFramesPerJob);
  EXPECT_EQ(FrameBytes(10, 10), 1200u);
}

// A job's memory: its frames, the pending frames' memory it may fill, and its bookkeeping
// per frame, which alone grows with a 100,000-frame job.
TEST(JobMemoryTest, JobMemoryAddsPendingFramesAndBookkeeping) {
  const uint64_t frame = FrameBytes(10, 10);
  EXPECT_EQ(JobMemoryBytes(Search(10, 10, 10, 60), 4), 58 * frame + 60 * kBookkeepingBytesPerFrame);
  // 2.5 frames of pending memory hold 2 frames.
  EXPECT_EQ(JobMemoryBytes(Search(10, 10, 10, 60, frame * 5 / 2), 1),
            (25 + 2) * frame + 60 * kBookkeepingBytesPerFrame);
  EXPECT_EQ(JobMemoryBytes(Search(10, 10, 10, 100000), 1), 25 * frame + 100000 * kBookkeepingBytesPerFrame);
  // auto's survey samples come on top of guarded's frames.
  JobMemoryShape guarded = RequestedJobShape(Strategy::kAuto, 0, 60, true, 64, 64, 0);
  EXPECT_EQ(guarded.strategy, Strategy::kGuarded);
  EXPECT_TRUE(guarded.surveyBinWidth);
  JobMemoryShape unsurveyed = guarded;
  unsurveyed.surveyBinWidth = false;
  EXPECT_EQ(JobMemoryBytes(guarded, 1) - JobMemoryBytes(unsurveyed, 1), uint64_t{64} * 3 * 4 * (3 * 15 + 1));
}

// How many bins fit in a budget, and the message for a job that fits not even alone.
TEST(JobMemoryTest, LiveBinsWithinABudgetAndTheShortfall) {
  const JobMemoryShape job = Search(10, 10, 10, 60);
  const uint64_t bookkeeping = 60 * kBookkeepingBytesPerFrame, frame = FrameBytes(10, 10);
  EXPECT_EQ(LiveBinsWithin(58 * frame + bookkeeping, job, 4), 4);
  EXPECT_EQ(LiveBinsWithin(58 * frame + bookkeeping - 1, job, 4), 3);
  EXPECT_EQ(LiveBinsWithin(25 * frame + bookkeeping, job, 4), 1);
  EXPECT_EQ(LiveBinsWithin(25 * frame + bookkeeping - 1, job, 4), 0);
  EXPECT_EQ(MemoryShortfall(25 * frame + bookkeeping, job), "");
  const std::string shortfall = MemoryShortfall(25 * frame, job);
  EXPECT_NE(shortfall.find("holds up to 25 of them"), std::string::npos) << shortfall;
  EXPECT_NE(shortfall.find("it needs 33.0 KiB"), std::string::npos) << shortfall;
}

// The probe's job: 6144x6144, 100,000 frames, search at n = 10 needs 11 GiB even one bin
// at a time, so a farm of 8 GiB refuses it, one of 12 GiB runs it with one bin, one of
// 16 GiB with two.
TEST(JobMemoryTest, ALargeJobNeedsItsBinsFrames) {
  const JobMemoryShape probe = RequestedJobShape(Strategy::kSearch, 10, 100000, std::nullopt, 6144, 6144,
                                                 uint64_t{256} << 20);
  EXPECT_EQ(LiveBinsWithin(uint64_t{12} << 30, probe, 4), 1);
  EXPECT_EQ(LiveBinsWithin(uint64_t{16} << 30, probe, 4), 2);
  const std::string shortfall = MemoryShortfall(uint64_t{8} << 30, probe);
  EXPECT_NE(shortfall.find("it needs 10.55 GiB"), std::string::npos) << shortfall;
  EXPECT_NE(shortfall.find("the farm has 8.00 GiB for all its running jobs"), std::string::npos) << shortfall;
}

}  // namespace
}  // namespace tcfarm
