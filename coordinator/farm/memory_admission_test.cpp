// The farm's memory admits a job that fits beside the running ones, holds back one that
// does not, and lets later jobs pass a held one only until it has waited long enough.
#include "coordinator/farm/memory_admission.h"

#include <gtest/gtest.h>

#include "coordinator/planner/job_memory.h"
#include "coordinator/planner/planner.h"

namespace tcfarm {
namespace {

JobRecord SearchJob(uint64_t id) {
  JobRecord job;
  job.id = id;
  job.spec.strategy = Strategy::kSearch;
  job.spec.binWidth = 10;
  job.spec.lastFrame = 59;
  job.spec.frameSize = {64, 64};
  return job;
}

uint64_t OneBin(const JobRecord& job) {
  return JobMemoryBytes(RequestedJobShape(job.spec.strategy, job.spec.binWidth, job.FrameCount(), std::nullopt,
                                          job.spec.frameSize.width, job.spec.frameSize.height, 0),
                        1);
}

TEST(MemoryAdmissionTest, WithoutALimitEveryJobIsAdmittedAndGivenNothing) {
  FakeClock clock;
  MemoryAdmission admission(MemoryBudget{}, clock);
  uint64_t granted = 7;
  bool passable = true;
  EXPECT_TRUE(admission.Admits(SearchJob(1), uint64_t{1} << 40, &granted, &passable));
  EXPECT_EQ(granted, 7u);
}

TEST(MemoryAdmissionTest, AJobThatFitsIsGrantedWhatItsBinsNeed) {
  FakeClock clock;
  const JobRecord job = SearchJob(1);
  MemoryAdmission admission(MemoryBudget{10 * OneBin(job), 0, Milliseconds{1000}}, clock);
  uint64_t granted = 0;
  bool passable = true;
  ASSERT_TRUE(admission.Admits(job, 0, &granted, &passable));
  EXPECT_GE(granted, OneBin(job));
  EXPECT_LE(granted, 10 * OneBin(job));
}

TEST(MemoryAdmissionTest, AHeldJobMayBePassedOnlyUntilItHasWaitedLongEnough) {
  FakeClock clock;
  const JobRecord job = SearchJob(1);
  const uint64_t budget = 2 * OneBin(job);
  MemoryAdmission admission(MemoryBudget{budget, 0, Milliseconds{1000}}, clock);
  uint64_t granted = 0;
  bool passable = true;
  admission.BeginLook();
  EXPECT_FALSE(admission.Admits(job, budget, &granted, &passable));  // the running jobs hold it all
  EXPECT_TRUE(passable);
  admission.EndLook();
  clock.Advance(Milliseconds{1000});
  admission.BeginLook();
  EXPECT_FALSE(admission.Admits(job, budget, &granted, &passable));
  EXPECT_FALSE(passable);  // waited since the first look
  admission.EndLook();
}

TEST(MemoryAdmissionTest, AJobNotHeldInALookStartsItsWaitOver) {
  FakeClock clock;
  const JobRecord job = SearchJob(1);
  const uint64_t budget = 2 * OneBin(job);
  MemoryAdmission admission(MemoryBudget{budget, 0, Milliseconds{1000}}, clock);
  uint64_t granted = 0;
  bool passable = true;
  admission.BeginLook();
  admission.Admits(job, budget, &granted, &passable);
  admission.EndLook();
  admission.BeginLook();  // a look that did not reach it
  admission.EndLook();
  clock.Advance(Milliseconds{1000});
  admission.BeginLook();
  EXPECT_FALSE(admission.Admits(job, budget, &granted, &passable));
  EXPECT_TRUE(passable);
  admission.EndLook();
}

TEST(MemoryAdmissionTest, AJobThatNeverFitsIsAdmittedWithTheWholeBudgetToFail) {
  FakeClock clock;
  const JobRecord job = SearchJob(1);
  const uint64_t budget = OneBin(job) / 2;
  MemoryAdmission admission(MemoryBudget{budget, 0, Milliseconds{1000}}, clock);
  uint64_t granted = 0;
  bool passable = true;
  EXPECT_TRUE(admission.Admits(job, budget, &granted, &passable));
  EXPECT_EQ(granted, budget);
}

}  // namespace
}  // namespace tcfarm
