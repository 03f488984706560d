// A job's frame records: a frame is recorded only once its files are in place, the plan
// goes first, and what the store refuses stays owed.
#include "coordinator/farm/frame_records.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <random>

namespace tcfarm {
namespace {

namespace fs = std::filesystem;

class FrameRecordsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    folder_ = fs::temp_directory_path() / ("tcfarm_frame_records_" + std::to_string(std::random_device()()));
    fs::create_directories(folder_);
    store_ = std::make_unique<JobStore>(folder_ / "jobs.sqlite");
    JobSpec spec;
    spec.sceneJson = R"({"camera":{}})";
    spec.sceneHash = "ab12";
    spec.firstFrame = 1;
    spec.lastFrame = 4;
    spec.frameSize = {8, 6};
    id_ = store_->Submit(spec);
    ASSERT_TRUE(store_->ClaimNext());
  }
  void TearDown() override {
    store_.reset();
    fs::remove_all(folder_);
  }
  std::vector<int> Recorded() const {
    std::vector<int> frames;
    for (const RecordedFrame& frame : store_->RecordedFrames(id_)) frames.push_back(frame.frame);
    return frames;
  }

  fs::path folder_;
  std::unique_ptr<JobStore> store_;
  uint64_t id_ = 0;
};

TEST_F(FrameRecordsTest, AFrameIsRecordedOnlyOnceWritten) {
  FrameRecords records(id_, 48, {}, 0);
  records.Writing(2, 10);
  records.Writing(3, 48);
  EXPECT_TRUE(records.AnyWriting());
  EXPECT_FALSE(records.Owed());
  records.Written(3);
  EXPECT_TRUE(records.Owed());
  ASSERT_TRUE(records.Flush(*store_));
  EXPECT_EQ(Recorded(), (std::vector<int>{3}));
  EXPECT_EQ(records.recorded(), 1);
  EXPECT_EQ(records.WritingFrames(), (std::vector<int>{2}));
  EXPECT_FALSE(records.Owed());
  const std::vector<RecordedFrame> frames = store_->RecordedFrames(id_);
  EXPECT_EQ(frames[0].traced, 48u);
  EXPECT_EQ(frames[0].copied, 0u);
}

TEST_F(FrameRecordsTest, AFrameNeverWritingIsNotRecordedAndDroppedOnesNeverAre) {
  FrameRecords records(id_, 48, {}, 0);
  records.Written(1);
  records.Writing(2, 10);
  records.DropWriting();
  records.Written(2);
  EXPECT_FALSE(records.AnyWriting());
  ASSERT_TRUE(records.Flush(*store_));
  EXPECT_TRUE(Recorded().empty());
}

TEST_F(FrameRecordsTest, SavesThePlanAndForgetsMissingFrames) {
  ASSERT_TRUE(store_->RecordFrame(id_, 4, 48, 0));
  FrameRecords records(id_, 48, {4}, 1);
  records.SavePlan({{"strategy", "search"}});
  EXPECT_TRUE(records.Owed());
  ASSERT_TRUE(records.Flush(*store_));
  EXPECT_TRUE(Recorded().empty());
  EXPECT_EQ(store_->Get(id_)->plan, (nlohmann::json{{"strategy", "search"}}));
}

TEST_F(FrameRecordsTest, WhatAFullStoreRefusesStaysOwed) {
  FrameRecords records(id_, 48, {}, 0);
  records.SavePlan({{"pad", std::string(64 << 10, 'z')}});  // needs new pages, which a full disk refuses
  records.Writing(2, 48);
  records.Written(2);
  store_->CapFilePages(1);  // below what the file holds: every write is refused as on a full disk
  EXPECT_FALSE(records.Flush(*store_));
  EXPECT_FALSE(records.blocked().empty());
  EXPECT_TRUE(records.Owed());
  store_->CapFilePages(1 << 20);
  EXPECT_TRUE(records.Flush(*store_));
  EXPECT_TRUE(records.blocked().empty());
  EXPECT_EQ(Recorded(), (std::vector<int>{2}));
}

}  // namespace
}  // namespace tcfarm
