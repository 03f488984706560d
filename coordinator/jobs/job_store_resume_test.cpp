// A job the coordinator was running when it died (SIGKILL, power loss): what the next
// coordinator's JobStore finds and resumes. Beside job_store_test.cpp, which covers the
// store's other calls.
#include "coordinator/jobs/job_store.h"

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <atomic>
#include <filesystem>
#include <map>
#include <random>

namespace tcfarm {
namespace {

namespace fs = std::filesystem;

// Runs one SQL statement on the file through a separate, raw connection.
void RawExec(const fs::path& file, const char* sql) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(file.string().c_str(), &db), SQLITE_OK);
  EXPECT_EQ(sqlite3_exec(db, sql, nullptr, nullptr, nullptr), SQLITE_OK) << sqlite3_errmsg(db);
  sqlite3_close(db);
}

class JobStoreResumeTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::random_device random;
    file_ = fs::temp_directory_path() /
            ("tcfarm_job_store_resume_" + std::to_string(random()) + "_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name() + ".sqlite");
  }
  void TearDown() override {
    for (const char* suffix : {"", "-wal", "-shm"}) fs::remove(file_.string() + suffix);
  }

  std::unique_ptr<JobStore> Open() {
    return std::make_unique<JobStore>(file_, [this] { return nowMs_.load(); });
  }

  static JobSpec Spec(int frames) {
    JobSpec spec;
    spec.sceneJson = R"({"camera":{}})";
    spec.sceneHash = "ab12";
    spec.firstFrame = 0;
    spec.lastFrame = frames - 1;
    spec.frameSize = {8, 6};
    return spec;
  }

  // How many frames_written events name each frame, and the events marked recovered.
  struct Told {
    std::map<int, int> timesPerFrame;
    std::vector<JobEvent> recovered;
  };
  static Told FramesTold(const JobStore& store, uint64_t id) {
    Told told;
    for (const JobEvent& event : store.Events({id, 0, 1000})) {
      if (event.type != "frames_written") continue;
      for (const auto& range : event.fields.at("ranges")) {
        for (int frame = range[0].get<int>(); frame <= range[1].get<int>(); ++frame) ++told.timesPerFrame[frame];
      }
      if (event.fields.value("recovered", false)) told.recovered.push_back(event);
    }
    return told;
  }

  fs::path file_;
  std::atomic<int64_t> nowMs_{1'000};
};

// Frames recorded but not yet told when the process died (their frames_written event was
// still gathering) are told when the job is requeued: every recorded frame then has
// exactly one event, however many times the coordinator dies.
TEST_F(JobStoreResumeTest, FramesRecordedBeforeACrashAreToldOnResume) {
  uint64_t id = 0;
  {
    auto store = Open();
    id = store->Submit(Spec(60));
    ASSERT_TRUE(store->ClaimNext().has_value());
    for (int frame = 0; frame <= 12; ++frame) ASSERT_TRUE(store->RecordFrame(id, frame, 1, 47));
    ASSERT_TRUE(store->RecordFrame(id, 40, 1, 47));
    ASSERT_TRUE(store->RecordFrame(id, 41, 1, 47));
    // Frames 0..9 were told at the tenth; 10..12, 40 and 41 wait for the next flush.
    ASSERT_EQ(FramesTold(*store, id).timesPerFrame.size(), 10u);
  }  // dropped without a flush, as by SIGKILL

  nowMs_ = 5'000;
  auto store = Open();
  ASSERT_EQ(store->RequeueInterrupted(), std::vector<uint64_t>{id});
  Told told = FramesTold(*store, id);
  std::map<int, int> once;
  for (const RecordedFrame& frame : store->RecordedFrames(id)) once[frame.frame] = 1;
  ASSERT_EQ(once.size(), 15u);
  EXPECT_EQ(told.timesPerFrame, once);
  ASSERT_EQ(told.recovered.size(), 1u);
  EXPECT_EQ(told.recovered[0].fields["ranges"], (nlohmann::json{{10, 12}, {40, 41}}));
  EXPECT_EQ(told.recovered[0].fields["count"], 5);
  EXPECT_EQ(told.recovered[0].message,
            "5 frames written: 10..12, 40..41 (recovered: the coordinator stopped before telling them)");
  // Told before the requeued event, whose count includes them.
  const std::vector<JobEvent> events = store->Events({id, 0, 1000});
  ASSERT_GE(events.size(), 2u);
  EXPECT_EQ(events[events.size() - 2].seq, told.recovered[0].seq);
  EXPECT_EQ(events.back().type, "requeued");
  EXPECT_EQ(events.back().fields["frames_written"], 15);

  // Resumed, one more frame, and a second crash: only that frame is recovered.
  ASSERT_EQ(store->ClaimNext()->id, id);
  ASSERT_TRUE(store->RecordFrame(id, 13, 1, 47));
  store = Open();
  ASSERT_EQ(store->RequeueInterrupted(), std::vector<uint64_t>{id});
  told = FramesTold(*store, id);
  once[13] = 1;
  EXPECT_EQ(told.timesPerFrame, once);
  ASSERT_EQ(told.recovered.size(), 2u);
  EXPECT_EQ(told.recovered[1].message, "frame 13 written (recovered: the coordinator stopped before telling them)");
}

// A crash with nothing untold adds no frames_written event. A job with more untold frames
// than one event gathers (one a coordinator from before job events left running: its
// frames have no event at all) is told in events of at most kFramesPerEvent frames, as
// live ones are.
TEST_F(JobStoreResumeTest, RecoveredEventsGatherAtMostTenFrames) {
  uint64_t toldAll = 0, neverTold = 0;
  {
    auto store = Open();
    toldAll = store->Submit(Spec(60));
    neverTold = store->Submit(Spec(60));
    ASSERT_TRUE(store->ClaimNext().has_value());
    ASSERT_TRUE(store->ClaimNext().has_value());
    for (int frame = 0; frame < 3; ++frame) ASSERT_TRUE(store->RecordFrame(toldAll, frame, 1, 47));
    for (int frame = 0; frame < 25; ++frame) ASSERT_TRUE(store->RecordFrame(neverTold, frame, 1, 47));
    nowMs_ = 2'000;
    store->FlushFrameEvents();
  }
  RawExec(file_, ("DELETE FROM job_events WHERE job_id = " + std::to_string(neverTold)).c_str());

  auto store = Open();
  ASSERT_EQ(store->RequeueInterrupted(), (std::vector<uint64_t>{toldAll, neverTold}));
  EXPECT_TRUE(FramesTold(*store, toldAll).recovered.empty());
  const Told told = FramesTold(*store, neverTold);
  ASSERT_EQ(told.recovered.size(), 3u);
  for (const JobEvent& event : told.recovered) {
    EXPECT_LE(event.fields["count"].get<size_t>(), JobStore::kFramesPerEvent);
  }
  EXPECT_EQ(told.recovered[2].fields["ranges"], (nlohmann::json{{20, 24}}));
  std::map<int, int> once;
  for (int frame = 0; frame < 25; ++frame) once[frame] = 1;
  EXPECT_EQ(told.timesPerFrame, once);
}

}  // namespace
}  // namespace tcfarm
