#include "coordinator/farm/pending_frames.h"

#include <gtest/gtest.h>

#include <cstring>
#include <unistd.h>

namespace tcfarm {
namespace {

Image Frame(int seed, int width = 5, int height = 3) {
  Image image{width, height, {}};
  for (size_t i = 0; i < image.PixelCount() * 3; ++i) image.rgb.push_back(seed * 1000.0f + i * 0.125f);
  image.rgb[0] = -0.0f;  // bits, not just values, must come back
  return image;
}

bool SameBits(const Image& a, const Image& b) {
  return a.width == b.width && a.height == b.height && a.rgb.size() == b.rgb.size() &&
         std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float)) == 0;
}

bool SameBits(const std::optional<PendingFrames::Frame>& waiting, const Image& b) {
  return waiting && std::holds_alternative<Image>(*waiting) && SameBits(std::get<Image>(*waiting), b);
}

FrameChanges Changes(int seed) {
  FrameChanges changes{{1, 4, 6}, {}};
  for (int i = 0; i < 9; ++i) changes.rgb.push_back(seed * 1000.0f + i * 0.125f);
  changes.rgb[0] = -0.0f;
  return changes;
}

bool SameBits(const std::optional<PendingFrames::Frame>& waiting, const FrameChanges& b) {
  if (!waiting || !std::holds_alternative<FrameChanges>(*waiting)) return false;
  const FrameChanges& a = std::get<FrameChanges>(*waiting);
  return a.pixels == b.pixels && a.rgb.size() == b.rgb.size() &&
         std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float)) == 0;
}

std::filesystem::path FreshDirectory(const char* name) {
  auto path = std::filesystem::temp_directory_path() /
              ("tcfarm_pending_" + std::string(name) + "_" + std::to_string(getpid()));
  std::filesystem::remove_all(path);
  return path;
}

TEST(PendingFramesTest, WithinTheBudgetFramesStayInMemory) {
  const auto directory = FreshDirectory("memory");
  PendingFrames pending(directory / "spill", 10 * sizeof(float) * 45);
  for (int f = 0; f < 10; ++f) pending.Put(f, Frame(f));
  EXPECT_EQ(pending.SpilledFrames(), 0u);
  EXPECT_FALSE(std::filesystem::exists(directory / "spill"));
  for (int f = 9; f >= 0; --f) EXPECT_TRUE(SameBits(pending.Take(f), Frame(f))) << f;
  EXPECT_EQ(pending.HeldBytes(), 0u);
  EXPECT_FALSE(pending.Take(3).has_value());
}

TEST(PendingFramesTest, BeyondTheBudgetFramesSpillAndComeBackBitForBit) {
  const auto directory = FreshDirectory("spill");
  {
    PendingFrames pending(directory, 2 * sizeof(float) * 45);  // room for two frames
    for (int f = 0; f < 6; ++f) pending.Put(f, Frame(f));
    EXPECT_LE(pending.HeldBytes(), 2 * sizeof(float) * 45);
    EXPECT_EQ(pending.SpilledFrames(), 4u);
    EXPECT_EQ(pending.TotalSpilled(), 4u);
    for (int f : {5, 0, 3, 1, 4, 2}) {
      EXPECT_TRUE(SameBits(pending.Take(f), Frame(f))) << f;
    }
    EXPECT_EQ(pending.SpilledFrames(), 0u);
    EXPECT_TRUE(std::filesystem::is_empty(directory));  // taken spills are deleted
    pending.Put(7, Frame(7, 400, 300));  // alone larger than the budget: spilled at once
    EXPECT_EQ(pending.SpilledFrames(), 1u);
  }
  EXPECT_FALSE(std::filesystem::exists(directory));  // frames never taken leave nothing behind
}

TEST(PendingFramesTest, ChangesWaitAndSpillBitForBitBesideWholeFrames) {
  const auto directory = FreshDirectory("changes");
  // 3 pixels of changes take 3 * (4 + 12) bytes: room for one of them and nothing more.
  PendingFrames pending(directory, 48);
  pending.Put(1, Changes(1));
  EXPECT_EQ(pending.HeldBytes(), 48u);
  pending.Put(2, Changes(2));
  pending.Put(3, Frame(3));
  EXPECT_EQ(pending.SpilledFrames(), 2u);
  EXPECT_TRUE(SameBits(pending.Take(2), Changes(2)));
  EXPECT_TRUE(SameBits(pending.Take(3), Frame(3)));
  EXPECT_TRUE(SameBits(pending.Take(1), Changes(1)));
  EXPECT_EQ(pending.HeldBytes(), 0u);
}

TEST(PendingFramesTest, AnUnwritableSpillIsAClearError) {
  PendingFrames pending("/proc/tcfarm_cannot_be_here", 0);
  try {
    pending.Put(4, Frame(4));
    FAIL() << "expected FrameIoError";
  } catch (const FrameIoError& error) {
    EXPECT_NE(std::string(error.what()).find("cannot spill frame 4"), std::string::npos) << error.what();
  }
  EXPECT_FALSE(pending.Take(4).has_value());
}

}  // namespace
}  // namespace tcfarm
