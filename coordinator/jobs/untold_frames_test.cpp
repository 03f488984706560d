// The job store's untold frames: gathered per job, due once the first has waited.
#include "coordinator/jobs/untold_frames.h"

#include <gtest/gtest.h>

namespace tcfarm::jobs {
namespace {

TEST(UntoldFramesTest, GathersFramesPerJobInTheOrderRecorded) {
  UntoldFrames untold;
  untold.Add(1, 5, 100);
  untold.Add(2, 9, 100);
  untold.Add(1, 3, 200);
  EXPECT_EQ(untold.Of(1), (std::vector<int>{5, 3}));
  EXPECT_EQ(untold.Of(2), (std::vector<int>{9}));
  EXPECT_TRUE(untold.Of(3).empty());
}

TEST(UntoldFramesTest, AJobIsDueOnceItsFirstFrameWaitedTheInterval) {
  UntoldFrames untold;
  untold.Add(1, 0, 100);
  untold.Add(1, 1, 900);  // does not restart the wait
  untold.Add(2, 0, 600);
  EXPECT_TRUE(untold.DueAt(1099, 1000).empty());
  EXPECT_EQ(untold.DueAt(1100, 1000), (std::vector<uint64_t>{1}));
  EXPECT_EQ(untold.DueAt(1600, 1000), (std::vector<uint64_t>{1, 2}));
}

TEST(UntoldFramesTest, ClearedJobsStartTheirWaitOver) {
  UntoldFrames untold;
  untold.Add(1, 0, 100);
  untold.Clear(1);
  EXPECT_TRUE(untold.Of(1).empty());
  untold.Add(1, 1, 5000);
  EXPECT_TRUE(untold.DueAt(5500, 1000).empty());
}

TEST(UntoldFramesTest, ForgottenFramesLeaveTheRestAndTheLastTakesTheJob) {
  UntoldFrames untold;
  untold.Add(1, 4, 100);
  untold.Add(1, 6, 100);
  untold.Forget(1, {4, 8});
  EXPECT_EQ(untold.Of(1), (std::vector<int>{6}));
  untold.Forget(1, {6});
  EXPECT_TRUE(untold.DueAt(100000, 1000).empty());
}

}  // namespace
}  // namespace tcfarm::jobs
