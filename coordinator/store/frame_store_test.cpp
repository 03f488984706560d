#include "coordinator/store/frame_store.h"

#include <gtest/gtest.h>

namespace tcfarm {
namespace {

// The layout docs/operations.md ("Storage") and the API promise:
// STORE/<job>/frame_NNNN.{exr,png}, mask_NNNN.png and change_NNNN.png by the scene's
// frame number.
TEST(FrameStore, NamesEveryFileOfAJob) {
  const FrameStore store("/srv/store");
  EXPECT_EQ(store.JobFolder(7), "/srv/store/7");
  EXPECT_EQ(store.FramePath(7, 42, "exr"), "/srv/store/7/frame_0042.exr");
  EXPECT_EQ(store.FramePath(7, 3, "png"), "/srv/store/7/frame_0003.png");
  EXPECT_EQ(store.MaskPath(7, MaskKind::kTraced, 42), "/srv/store/7/mask_0042.png");
  EXPECT_EQ(store.MaskPath(7, MaskKind::kChange, 42), "/srv/store/7/change_0042.png");
  EXPECT_EQ(FrameStore::MaskFileName(MaskKind::kChange, 5), "change_0005.png");
  EXPECT_EQ(store.SpillFolder(7), "/srv/store/7/.pending");
}

TEST(FrameStore, MaskKindsByName) {
  EXPECT_EQ(MaskKindFromName("mask"), MaskKind::kTraced);
  EXPECT_EQ(MaskKindFromName("change"), MaskKind::kChange);
  EXPECT_FALSE(MaskKindFromName("traced").has_value());
}

}  // namespace
}  // namespace tcfarm
