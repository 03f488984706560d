#include "coordinator/farm/job_coherence.h"

#include <gtest/gtest.h>

#include <map>
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

// Frames told by their traced pixels give the masks and figures of whole frames, whether
// they come in their turn, wait in memory or wait on disk.
TEST_F(JobCoherenceTest, TracedPixelsGiveWhatWholeFramesGive) {
  std::mt19937 random(3);
  std::uniform_int_distribution<int> level(0, 1);
  std::bernoulli_distribution traced(0.3);
  std::vector<Image> frames{Image{6, 4, std::vector<float>(72, 0.0f)}};
  std::vector<std::vector<uint8_t>> tracedMasks{std::vector<uint8_t>(24, 1)};
  for (int f = 1; f < 12; ++f) {
    Image next = frames.back();
    std::vector<uint8_t> mask(24, 0);
    for (size_t p = 0; p < 24; ++p) {
      if (!traced(random)) continue;
      mask[p] = 1;
      next.rgb[3 * p + level(random)] = float(level(random));  // often its old value: a tie
    }
    frames.push_back(next);
    tracedMasks.push_back(mask);
  }
  const std::vector<int> order{3, 0, 1, 5, 4, 2, 7, 6, 8, 11, 10, 9};  // some ahead of their turn
  for (size_t memory : {size_t{1} << 20, size_t{0}}) {
    JobCoherence whole(folder_ / "whole", memory), byTraced(folder_ / "traced", memory);
    std::map<int, std::vector<uint8_t>> wholeMasks, tracedMasksOut;
    for (int f : order) {
      for (auto& mask : whole.Add(f, frames[f])) wholeMasks[mask.frame] = mask.unchanged;
      for (auto& mask : byTraced.Add(f, frames[f], &tracedMasks[f])) tracedMasksOut[mask.frame] = mask.unchanged;
    }
    EXPECT_EQ(tracedMasksOut, wholeMasks) << memory;
    EXPECT_EQ(wholeMasks.size(), frames.size());
    EXPECT_EQ(byTraced.analysis().Finish().ToJson(), whole.analysis().Finish().ToJson()) << memory;
    EXPECT_EQ(byTraced.FramesWaitedOnDisk(), memory == 0 ? 6u : 0u);  // 3, 5, 4, 7, 11, 10
  }
}

}  // namespace
}  // namespace tcfarm
