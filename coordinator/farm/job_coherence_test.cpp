#include "coordinator/farm/job_coherence.h"

#include <gtest/gtest.h>

#include <random>

namespace tcfarm {
namespace {

namespace fs = std::filesystem;

class JobCoherenceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    folder_ = fs::temp_directory_path() / ("tcfarm_coherence_" + std::to_string(std::random_device()()));
  }
  void TearDown() override { fs::remove_all(folder_); }
  fs::path folder_;
};

// Two pixels; frame f's first pixel is f, its second stays 0.
Image Frame(int f) { return Image{2, 1, {float(f), 0, 0, 0, 0, 0}}; }

TEST_F(JobCoherenceTest, FramesAheadOfTheirTurnWaitThenComeOutInOrder) {
  JobCoherence coherence(folder_ / ".pending", size_t{1} << 20);
  EXPECT_TRUE(coherence.Add(2, Frame(2)).empty());
  EXPECT_TRUE(coherence.Add(1, Frame(1)).empty());
  const std::vector<JobCoherence::ChangeMask> masks = coherence.Add(0, Frame(0));
  ASSERT_EQ(masks.size(), 3u);
  EXPECT_EQ(masks[0].frame, 0);
  EXPECT_EQ(masks[0].unchanged, (std::vector<uint8_t>{1, 1}));  // nothing to change from
  EXPECT_EQ(masks[1].frame, 1);
  EXPECT_EQ(masks[1].unchanged, (std::vector<uint8_t>{0, 1}));
  EXPECT_EQ(masks[2].frame, 2);
  EXPECT_EQ(coherence.analysis().FrameCount(), 3);
  EXPECT_DOUBLE_EQ(coherence.analysis().frameToFrame().Mean(), 0.5);
  EXPECT_EQ(coherence.FramesWaitedOnDisk(), 0u);
}

TEST_F(JobCoherenceTest, WithoutMemoryFramesWaitOnDisk) {
  {
    JobCoherence coherence(folder_ / ".pending", 0);
    EXPECT_TRUE(coherence.Add(1, Frame(1)).empty());
    EXPECT_EQ(coherence.FramesWaitedOnDisk(), 1u);
    ASSERT_EQ(coherence.Add(0, Frame(0)).size(), 2u);
  }
  EXPECT_FALSE(fs::exists(folder_ / ".pending"));
}

}  // namespace
}  // namespace tcfarm
