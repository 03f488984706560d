#include "coordinator/jobs/job_store.h"

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <algorithm>
#include <chrono>
#include <atomic>
#include <fstream>
#include <functional>
#include <random>
#include <set>
#include <thread>

#include <sys/wait.h>
#include <unistd.h>

namespace tcfarm {
namespace {

namespace fs = std::filesystem;

// A fresh folder per test, removed afterwards, so tests never see each other's files.
class JobStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::random_device random;
    folder_ = fs::temp_directory_path() /
              ("tcfarm_job_store_" + std::to_string(random()) + "_" +
               ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(folder_);
    file_ = folder_ / "jobs.sqlite";
  }
  void TearDown() override { fs::remove_all(folder_); }

  std::unique_ptr<JobStore> Open() {
    return std::make_unique<JobStore>(file_, [this] { return nowMs_.load(); });
  }

  static JobSpec Spec(int priority = 0, const std::string& name = "") {
    JobSpec spec;
    spec.name = name;
    spec.sceneJson = R"({"camera":{}})";
    spec.sceneHash = "ab12";
    spec.firstFrame = 1;
    spec.lastFrame = 10;
    spec.priority = priority;
    spec.frameSize = {8, 6};
    return spec;
  }

  fs::path folder_;
  fs::path file_;
  std::atomic<int64_t> nowMs_{1'000};
};

// Runs one SQL statement on the file through a separate, raw connection.
void RawExec(const fs::path& file, const char* sql) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(file.string().c_str(), &db), SQLITE_OK);
  EXPECT_EQ(sqlite3_exec(db, sql, nullptr, nullptr, nullptr), SQLITE_OK) << sqlite3_errmsg(db);
  sqlite3_close(db);
}

TEST(JobStateTest, NamesRoundTrip) {
  for (JobState state : {JobState::kQueued, JobState::kRunning, JobState::kCompleted,
                         JobState::kFailed, JobState::kCanceled}) {
    EXPECT_EQ(JobStateFromString(ToString(state)), state);
  }
  EXPECT_EQ(ToString(JobState::kCanceled), "canceled");
  EXPECT_FALSE(JobStateFromString("cancelled").has_value());
  EXPECT_FALSE(JobStateFromString("").has_value());
}

TEST(JobRecordTest, TracedPixelRatioOverFinishedFrames) {
  JobRecord record;
  EXPECT_EQ(record.TracedPixelRatio(100), 0.0);
  record.framesDone = 4;
  record.tracedPixels = 100;
  EXPECT_DOUBLE_EQ(record.TracedPixelRatio(100), 0.25);
  EXPECT_EQ(record.TracedPixelRatio(0), 0.0);
}

TEST_F(JobStoreTest, SubmitGetRoundTripsEveryField) {
  auto store = Open();
  JobSpec spec;
  spec.name = "orbit 'quoted'; DROP TABLE jobs; --";
  spec.sceneJson = R"({"camera":{"fov":45},"text":"ünïcode"})";
  spec.sceneHash = std::string(64, 'f');
  spec.firstFrame = -3;
  spec.lastFrame = 7;
  spec.strategy = Strategy::kBrute;
  spec.binWidth = 4;
  spec.tolerance = 0.125;
  spec.priority = -2;
  spec.options = {{"verify", {{"frames", "sampled"}, {"every", 5}}}};
  spec.frameSize = {640, 360};
  spec.cameraOrLightsChange = true;
  spec.deformingMeshes = true;
  nowMs_ = 42;
  const uint64_t id = store->Submit(spec);

  const std::optional<JobRecord> record = store->Get(id);
  ASSERT_TRUE(record.has_value());
  EXPECT_EQ(record->id, id);
  EXPECT_EQ(record->spec.name, spec.name);
  EXPECT_EQ(record->spec.sceneJson, spec.sceneJson);
  EXPECT_EQ(record->spec.sceneHash, spec.sceneHash);
  EXPECT_EQ(record->spec.firstFrame, -3);
  EXPECT_EQ(record->spec.lastFrame, 7);
  EXPECT_EQ(record->spec.strategy, Strategy::kBrute);
  EXPECT_EQ(record->spec.binWidth, 4);
  EXPECT_EQ(record->spec.tolerance, 0.125);
  EXPECT_EQ(record->spec.priority, -2);
  EXPECT_EQ(record->spec.options, spec.options);
  EXPECT_EQ(record->spec.frameSize.width, 640);
  EXPECT_EQ(record->spec.frameSize.height, 360);
  EXPECT_EQ(record->spec.cameraOrLightsChange, std::optional<bool>(true));
  EXPECT_EQ(record->spec.deformingMeshes, std::optional<bool>(true));
  EXPECT_EQ(record->state, JobState::kQueued);
  EXPECT_EQ(record->error, "");
  EXPECT_EQ(record->submittedMs, 42);
  EXPECT_EQ(record->startedMs, 0);
  EXPECT_EQ(record->finishedMs, 0);
  EXPECT_EQ(record->framesDone, 0);
  EXPECT_EQ(record->tracedPixels, 0u);
  EXPECT_EQ(record->copiedPixels, 0u);
  EXPECT_EQ(record->FrameCount(), 11);
  EXPECT_EQ(record->tracedPerFrame, std::vector<int64_t>(11, -1));
  EXPECT_EQ(record->stats, nlohmann::json::object());
  EXPECT_EQ(store->CountInState(JobState::kQueued), 1u);
}

TEST_F(JobStoreTest, GetUnknownIsEmpty) {
  auto store = Open();
  EXPECT_FALSE(store->Get(12345).has_value());
}

TEST_F(JobStoreTest, SubmitRejectsBadSpec) {
  auto store = Open();
  JobSpec backwards = Spec();
  backwards.lastFrame = 0;
  EXPECT_THROW(store->Submit(backwards), std::invalid_argument);
  JobSpec noBins = Spec();
  noBins.binWidth = 0;
  EXPECT_THROW(store->Submit(noBins), std::invalid_argument);
  JobSpec nanTolerance = Spec();
  nanTolerance.tolerance = std::nan("");
  EXPECT_THROW(store->Submit(nanTolerance), std::invalid_argument);
  EXPECT_EQ(store->List().size(), 0u);
}

TEST_F(JobStoreTest, ListIsNewestFirstFilteredLimitedAndLight) {
  auto store = Open();
  const uint64_t first = store->Submit(Spec(0, "a"));
  const uint64_t second = store->Submit(Spec(0, "b"));
  const uint64_t third = store->Submit(Spec(0, "c"));
  ASSERT_TRUE(store->ClaimNext().has_value());  // claims `first`

  const std::vector<JobRecord> all = store->List();
  ASSERT_EQ(all.size(), 3u);
  EXPECT_EQ(all[0].id, third);
  EXPECT_EQ(all[1].id, second);
  EXPECT_EQ(all[2].id, first);
  for (const JobRecord& record : all) {
    EXPECT_TRUE(record.spec.sceneJson.empty());
    EXPECT_TRUE(record.tracedPerFrame.empty());
    EXPECT_EQ(record.spec.sceneHash, "ab12");
  }
  const std::vector<JobRecord> queued = store->List(JobState::kQueued);
  ASSERT_EQ(queued.size(), 2u);
  EXPECT_EQ(queued[0].id, third);
  EXPECT_EQ(store->List(JobState::kRunning).at(0).id, first);
  EXPECT_EQ(store->List(std::nullopt, 1).size(), 1u);
  EXPECT_EQ(store->List(std::nullopt, 0).size(), 3u);  // no limit
  EXPECT_TRUE(store->List(JobState::kFailed).empty());
}

TEST_F(JobStoreTest, ClaimNextTakesHighestPriorityThenOldest) {
  auto store = Open();
  const uint64_t lowOld = store->Submit(Spec(0));
  const uint64_t highOld = store->Submit(Spec(5));
  const uint64_t lowNew = store->Submit(Spec(0));
  const uint64_t highNew = store->Submit(Spec(5));
  const uint64_t negative = store->Submit(Spec(-1));

  nowMs_ = 7'000;
  const std::optional<JobRecord> claimed = store->ClaimNext();
  ASSERT_TRUE(claimed.has_value());
  EXPECT_EQ(claimed->id, highOld);
  EXPECT_EQ(claimed->state, JobState::kRunning);
  EXPECT_EQ(claimed->startedMs, 7'000);
  EXPECT_EQ(claimed->spec.sceneJson, Spec().sceneJson);  // the worker-facing side needs it

  std::vector<uint64_t> order;
  while (std::optional<JobRecord> next = store->ClaimNext()) order.push_back(next->id);
  EXPECT_EQ(order, (std::vector<uint64_t>{highNew, lowOld, lowNew, negative}));
  EXPECT_EQ(store->CountInState(JobState::kRunning), 5u);
}

// The farm admits jobs by memory: it is shown the queued jobs in claim order, each without
// its scene, and the first it admits is claimed; the others stay queued.
TEST_F(JobStoreTest, ClaimNextClaimsTheFirstJobAdmitted) {
  auto store = Open();
  const uint64_t high = store->Submit(Spec(5, "high")), low = store->Submit(Spec(0, "low"));
  const uint64_t lower = store->Submit(Spec(-1, "lower"));
  std::vector<uint64_t> shown;
  const std::optional<JobRecord> claimed = store->ClaimNext([&](const JobRecord& job) {
    shown.push_back(job.id);
    EXPECT_TRUE(job.spec.sceneJson.empty());
    return job.spec.name == "low";
  });
  ASSERT_TRUE(claimed.has_value());
  EXPECT_EQ(claimed->id, low);
  EXPECT_EQ(claimed->spec.sceneJson, Spec().sceneJson);  // the claimed record is whole
  EXPECT_EQ(shown, (std::vector<uint64_t>{high, low}));
  EXPECT_EQ(store->StateOf(low), JobState::kRunning);
  EXPECT_EQ(store->StateOf(high), JobState::kQueued);
  EXPECT_FALSE(store->ClaimNext([](const JobRecord&) { return false; }).has_value());
  EXPECT_EQ(store->CountInState(JobState::kQueued), 2u);
  EXPECT_EQ(store->ClaimNext()->id, high);
  EXPECT_EQ(store->ClaimNext()->id, lower);
}

TEST_F(JobStoreTest, ClaimNextOnEmptyQueueIsEmpty) {
  auto store = Open();
  EXPECT_FALSE(store->ClaimNext().has_value());
  const uint64_t id = store->Submit(Spec());
  store->Cancel(id);
  EXPECT_FALSE(store->ClaimNext().has_value());  // only final jobs left
}

// Claims from several threads (and, to exercise the file lock too, two stores on the same
// file): every job is claimed exactly once.
TEST_F(JobStoreTest, ConcurrentClaimNeverClaimsAJobTwice) {
  auto storeA = Open();
  auto storeB = Open();
  constexpr int kJobs = 100;
  std::set<uint64_t> submitted;
  for (int i = 0; i < kJobs; ++i) submitted.insert(storeA->Submit(Spec(i % 3)));

  constexpr int kThreads = 4;
  std::vector<std::vector<uint64_t>> claimedBy(kThreads);
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    JobStore& store = t % 2 == 0 ? *storeA : *storeB;
    threads.emplace_back([&store, &claimed = claimedBy[t]] {
      while (std::optional<JobRecord> job = store.ClaimNext()) claimed.push_back(job->id);
    });
  }
  for (std::thread& thread : threads) thread.join();

  std::multiset<uint64_t> claimed;
  for (const auto& ids : claimedBy) claimed.insert(ids.begin(), ids.end());
  EXPECT_EQ(claimed.size(), static_cast<size_t>(kJobs));
  EXPECT_EQ(std::set<uint64_t>(claimed.begin(), claimed.end()), submitted);
  EXPECT_EQ(storeA->CountInState(JobState::kRunning), static_cast<size_t>(kJobs));
  EXPECT_EQ(storeB->CountInState(JobState::kQueued), 0u);
}

TEST_F(JobStoreTest, CancelQueuedAndRunningButNotFinishedOrUnknown) {
  auto store = Open();
  const uint64_t running = store->Submit(Spec(1));
  const uint64_t queued = store->Submit(Spec(0));
  const uint64_t completed = store->Submit(Spec(2));
  ASSERT_EQ(store->ClaimNext()->id, completed);
  ASSERT_TRUE(store->Complete(completed, {}));
  ASSERT_EQ(store->ClaimNext()->id, running);

  nowMs_ = 9'000;
  EXPECT_TRUE(store->Cancel(queued));
  EXPECT_TRUE(store->Cancel(running));
  EXPECT_FALSE(store->Cancel(completed));
  EXPECT_FALSE(store->Cancel(999));
  EXPECT_FALSE(store->Cancel(queued));  // already canceled: final

  EXPECT_EQ(store->Get(queued)->state, JobState::kCanceled);
  EXPECT_EQ(store->Get(queued)->finishedMs, 9'000);
  EXPECT_EQ(store->Get(running)->state, JobState::kCanceled);
  EXPECT_EQ(store->Get(completed)->state, JobState::kCompleted);
  EXPECT_EQ(store->CountInState(JobState::kCanceled), 2u);
}

TEST_F(JobStoreTest, LateResultsNeverResurrectACanceledJob) {
  auto store = Open();
  const uint64_t id = store->Submit(Spec());
  ASSERT_TRUE(store->ClaimNext().has_value());
  ASSERT_TRUE(store->RecordFrame(id, 1, 100, 0));
  nowMs_ = 5'000;
  ASSERT_TRUE(store->Cancel(id));
  nowMs_ = 6'000;

  EXPECT_FALSE(store->Complete(id, {{"coherence", 0.9}}));
  EXPECT_FALSE(store->RecordFrame(id, 2, 100, 0));
  EXPECT_FALSE(store->SetStats(id, {{"late", true}}));
  EXPECT_FALSE(store->Fail(id, "worker lost"));

  const JobRecord record = *store->Get(id);
  EXPECT_EQ(record.state, JobState::kCanceled);
  EXPECT_EQ(record.finishedMs, 5'000);
  EXPECT_EQ(record.framesDone, 1);  // the partial progress stays visible
  EXPECT_EQ(record.error, "");
  EXPECT_EQ(record.stats, nlohmann::json::object());
}

TEST_F(JobStoreTest, CompleteOnlyFromRunningAndMergesStats) {
  auto store = Open();
  const uint64_t id = store->Submit(Spec());
  EXPECT_FALSE(store->Complete(id, {}));  // still queued
  ASSERT_TRUE(store->ClaimNext().has_value());
  ASSERT_TRUE(store->SetStats(id, {{"coherence", 0.5}, {"timings", {{"traceS", 1.0}}}}));
  ASSERT_TRUE(store->SetStats(id, {{"timings", {{"planS", 0.25}}}}));
  nowMs_ = 8'000;
  ASSERT_TRUE(store->Complete(id, {{"coherence", 0.75}, {"relativeCost", 0.2}}));
  EXPECT_FALSE(store->Complete(id, {{"coherence", 0.0}}));  // final: stays as it was

  const JobRecord record = *store->Get(id);
  EXPECT_EQ(record.state, JobState::kCompleted);
  EXPECT_EQ(record.finishedMs, 8'000);
  const nlohmann::json expected = {{"coherence", 0.75},
                                   {"relativeCost", 0.2},
                                   {"timings", {{"traceS", 1.0}, {"planS", 0.25}}}};
  EXPECT_EQ(record.stats, expected);
  EXPECT_FALSE(store->SetStats(id, {{"x", 1}}));
  EXPECT_FALSE(store->Fail(id, "too late"));
}

TEST_F(JobStoreTest, FailRecordsTheErrorFromQueuedOrRunning) {
  auto store = Open();
  const uint64_t running = store->Submit(Spec(1));
  const uint64_t queued = store->Submit(Spec(0));
  ASSERT_EQ(store->ClaimNext()->id, running);
  nowMs_ = 3'000;
  EXPECT_TRUE(store->Fail(running, "scene hash mismatch on worker w3"));
  EXPECT_TRUE(store->Fail(queued, "scene rejected"));
  EXPECT_FALSE(store->Fail(running, "again"));
  EXPECT_FALSE(store->Fail(4242, "unknown"));

  EXPECT_EQ(store->Get(running)->state, JobState::kFailed);
  EXPECT_EQ(store->Get(running)->error, "scene hash mismatch on worker w3");
  EXPECT_EQ(store->Get(running)->finishedMs, 3'000);
  EXPECT_EQ(store->Get(queued)->error, "scene rejected");
  EXPECT_FALSE(store->Cancel(running));
  EXPECT_EQ(store->CountInState(JobState::kFailed), 2u);
}

TEST_F(JobStoreTest, RecordFrameUpdatesCountersAndPerFrameList) {
  auto store = Open();
  const uint64_t id = store->Submit(Spec());  // frames 1..10
  EXPECT_FALSE(store->RecordFrame(id, 1, 5, 5));  // queued: ignored
  ASSERT_TRUE(store->ClaimNext().has_value());

  EXPECT_TRUE(store->RecordFrame(id, 1, 1000, 0));
  EXPECT_TRUE(store->RecordFrame(id, 10, 30, 970));
  EXPECT_TRUE(store->RecordFrame(id, 4, 0, 1000));
  EXPECT_FALSE(store->RecordFrame(id, 4, 0, 1000));  // duplicate result: counted once
  EXPECT_THROW(store->RecordFrame(id, 11, 1, 1), std::out_of_range);
  EXPECT_THROW(store->RecordFrame(id, 0, 1, 1), std::out_of_range);
  EXPECT_FALSE(store->RecordFrame(777, 1, 1, 1));  // unknown job: ignored

  const JobRecord record = *store->Get(id);
  EXPECT_EQ(record.framesDone, 3);
  EXPECT_EQ(record.tracedPixels, 1030u);
  EXPECT_EQ(record.copiedPixels, 1970u);
  const std::vector<int64_t> expected = {1000, -1, -1, 0, -1, -1, -1, -1, -1, 30};
  EXPECT_EQ(record.tracedPerFrame, expected);
  EXPECT_DOUBLE_EQ(record.TracedPixelRatio(1000), 1030.0 / 3000.0);
  EXPECT_EQ(store->List().at(0).framesDone, 3);
}

TEST_F(JobStoreTest, LongJobStaysCheapToList) {
  auto store = Open();
  JobSpec spec = Spec();
  spec.firstFrame = 0;
  spec.lastFrame = 99'999;
  const uint64_t id = store->Submit(spec);
  ASSERT_TRUE(store->ClaimNext().has_value());
  for (int frame = 0; frame < 100'000; frame += 1000) store->RecordFrame(id, frame, 7, 3);

  const JobRecord record = *store->Get(id);
  ASSERT_EQ(record.tracedPerFrame.size(), 100'000u);
  EXPECT_EQ(record.tracedPerFrame[1000], 7);
  EXPECT_EQ(record.tracedPerFrame[1001], -1);
  EXPECT_EQ(record.framesDone, 100);
  EXPECT_TRUE(store->List().at(0).tracedPerFrame.empty());
}

TEST_F(JobStoreTest, EverythingPersistsAcrossReopen) {
  uint64_t done = 0, failed = 0, queued = 0;
  {
    auto store = Open();
    done = store->Submit(Spec(3, "done"));
    failed = store->Submit(Spec(2, "failed"));
    queued = store->Submit(Spec(1, "queued"));
    store->ClaimNext();
    store->RecordFrame(done, 2, 11, 22);
    store->Complete(done, {{"coherence", 0.8}});
    store->ClaimNext();
    store->Fail(failed, "out of memory");
  }
  auto store = Open();
  const JobRecord doneRecord = *store->Get(done);
  EXPECT_EQ(doneRecord.state, JobState::kCompleted);
  EXPECT_EQ(doneRecord.spec.name, "done");
  EXPECT_EQ(doneRecord.spec.sceneJson, Spec().sceneJson);
  EXPECT_EQ(doneRecord.tracedPixels, 11u);
  EXPECT_EQ(doneRecord.copiedPixels, 22u);
  EXPECT_EQ(doneRecord.tracedPerFrame[1], 11);
  EXPECT_EQ(doneRecord.stats, (nlohmann::json{{"coherence", 0.8}}));
  EXPECT_EQ(store->Get(failed)->error, "out of memory");
  EXPECT_EQ(store->Get(queued)->state, JobState::kQueued);
  EXPECT_TRUE(store->RequeueInterrupted().empty());  // nothing was running
  // Ids keep growing after a reopen, so an old id never names a new job.
  EXPECT_GT(store->Submit(Spec()), queued);
}

TEST_F(JobStoreTest, RequeueInterruptedAfterACrash) {
  uint64_t interrupted = 0, waiting = 0, finished = 0;
  {
    auto store = Open();
    finished = store->Submit(Spec(9));
    interrupted = store->Submit(Spec(5));
    waiting = store->Submit(Spec(0));
    store->ClaimNext();
    store->Complete(finished, {});
    store->ClaimNext();
    store->SetPlan(interrupted, {{"strategy", "exact"}, {"bin_width", 4}});
    store->RecordFrame(interrupted, 3, 50, 50);
    store->SetStats(interrupted, {{"coherence", 0.4}});
  }  // the process "dies" with `interrupted` running

  nowMs_ = 9'000;
  auto store = Open();
  EXPECT_EQ(store->RequeueInterrupted(), std::vector<uint64_t>{interrupted});
  JobRecord record = *store->Get(interrupted);
  // Queued again with what it had written: the next claim resumes it.
  EXPECT_EQ(record.state, JobState::kQueued);
  EXPECT_EQ(record.startedMs, 1'000);
  EXPECT_EQ(record.framesDone, 1);
  EXPECT_EQ(record.tracedPixels, 50u);
  EXPECT_EQ(record.tracedPerFrame[2], 50);
  EXPECT_EQ(record.plan, (nlohmann::json{{"strategy", "exact"}, {"bin_width", 4}}));
  EXPECT_EQ(store->Get(finished)->state, JobState::kCompleted);
  EXPECT_EQ(store->Get(waiting)->state, JobState::kQueued);
  EXPECT_TRUE(store->RequeueInterrupted().empty());
  // Its priority still puts it ahead of the job that was waiting; it keeps its start time.
  record = *store->ClaimNext();
  EXPECT_EQ(record.id, interrupted);
  EXPECT_EQ(record.startedMs, 1'000);
  EXPECT_FALSE(store->RecordFrame(interrupted, 3, 50, 50));  // counted once, before the crash
  EXPECT_TRUE(store->RecordFrame(interrupted, 4, 60, 40));
  EXPECT_EQ(store->Get(interrupted)->framesDone, 2);
}

// A real crash: a child process claims a job and dies without closing the database, so
// the job's last commits are still in the WAL file when the next process opens it.
TEST_F(JobStoreTest, RequeueInterruptedAfterTheProcessDies) {
  const uint64_t id = Open()->Submit(Spec());
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    auto store = Open();
    const bool claimed = store->ClaimNext().has_value() && store->RecordFrame(id, 2, 9, 1);
    _exit(claimed ? 0 : 1);  // no destructors: the connection is never closed
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);

  auto store = Open();
  EXPECT_EQ(store->Get(id)->state, JobState::kRunning);
  EXPECT_EQ(store->Get(id)->framesDone, 1);
  EXPECT_EQ(store->RequeueInterrupted(), std::vector<uint64_t>{id});
  EXPECT_EQ(store->Get(id)->state, JobState::kQueued);
  EXPECT_EQ(store->Get(id)->framesDone, 1);  // the frame the dead process recorded
}

// The database's disk full, simulated with a page cap: every write is refused with
// JobStoreFullError and changes nothing, reads go on, and once there is room the same
// calls succeed, with no job lost or doubled.
TEST_F(JobStoreTest, AFullDatabaseRefusesWritesAndRecovers) {
  auto store = Open();
  const uint64_t running = store->Submit(Spec(1));
  const uint64_t queued = store->Submit(Spec(0));
  ASSERT_EQ(store->ClaimNext()->id, running);
  ASSERT_TRUE(store->RecordFrame(running, 1, 10, 38));
  JobSpec large = Spec();
  large.sceneJson = "{\"pad\": \"" + std::string(64 << 10, 'x') + "\"}";
  store->CapFilePages(1);  // below what the file holds: no page can be added
  try {
    store->Submit(large);
    FAIL() << "a submit into a full database succeeded";
  } catch (const JobStoreFullError& e) {
    EXPECT_NE(std::string(e.what()).find("full"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(file_.string()), std::string::npos) << e.what();
  }
  for (int frame = 2; frame <= 10; ++frame) {
    try {
      store->RecordFrame(running, frame, 10, 38);
    } catch (const JobStoreFullError&) {
    }
  }
  // Reads work; what was refused left no trace (the frames that fit before the cap bit
  // are counted once each).
  EXPECT_EQ(store->List().size(), 2u);
  const int recorded = store->Get(running)->framesDone;
  EXPECT_EQ(store->CountInState(JobState::kQueued), 1u);

  store->CapFilePages(1 << 30);  // room again
  const uint64_t next = store->Submit(large);
  EXPECT_EQ(next, queued + 1);  // the refused submit took no id
  for (int frame = 2; frame <= 10; ++frame) store->RecordFrame(running, frame, 10, 38);
  EXPECT_EQ(store->Get(running)->framesDone, 10);
  EXPECT_GE(recorded, 1);
  EXPECT_TRUE(store->Complete(running, {{"done", true}}));
  EXPECT_EQ(store->List().size(), 3u);
}

TEST_F(JobStoreTest, EachTransitionOfAFullDatabaseIsRefusedWhole) {
  auto store = Open();
  const uint64_t id = store->Submit(Spec());
  const uint64_t other = store->Submit(Spec());
  ASSERT_TRUE(store->ClaimNext().has_value());
  // Pad the file so that the cap below leaves no free page for any write.
  JobSpec large = Spec();
  large.sceneJson = "{\"pad\": \"" + std::string(256 << 10, 'x') + "\"}";
  const uint64_t padding = store->Submit(large);
  ASSERT_TRUE(store->Cancel(padding));
  store->CapFilePages(1);
  int refused = 0;
  for (const std::function<void()>& write : std::vector<std::function<void()>>{
           [&] { store->SetStats(id, {{"big", std::string(64 << 10, 'y')}}); },
           [&] { store->SetPlan(id, {{"pad", std::string(64 << 10, 'z')}}); },
           [&] { store->Fail(id, std::string(64 << 10, 'w')); },
       }) {
    try {
      write();
    } catch (const JobStoreFullError&) {
      ++refused;
    }
  }
  EXPECT_EQ(refused, 3);
  const JobRecord record = *store->Get(id);
  EXPECT_EQ(record.state, JobState::kRunning);
  EXPECT_EQ(record.stats, nlohmann::json::object());
  EXPECT_EQ(record.plan, nlohmann::json::object());
  EXPECT_EQ(store->Get(other)->state, JobState::kQueued);
  store->CapFilePages(1 << 30);
  EXPECT_TRUE(store->Fail(id, "disk was full"));
}

TEST_F(JobStoreTest, ForgetFramesUncountsThem) {
  auto store = Open();
  const uint64_t id = store->Submit(Spec());
  ASSERT_TRUE(store->ClaimNext().has_value());
  store->RecordFrame(id, 1, 10, 38);
  store->RecordFrame(id, 2, 20, 28);
  store->ForgetFrames(id, {2, 5});  // 5 was never recorded
  const JobRecord record = *store->Get(id);
  EXPECT_EQ(record.framesDone, 1);
  EXPECT_EQ(record.tracedPixels, 10u);
  EXPECT_EQ(record.copiedPixels, 38u);
  EXPECT_EQ(record.tracedPerFrame[1], -1);
  EXPECT_TRUE(store->RecordFrame(id, 2, 20, 28));
}

TEST_F(JobStoreTest, StoreIdentityAndReservedIds) {
  auto store = Open();
  EXPECT_EQ(store->StoreId(), std::nullopt);
  EXPECT_EQ(store->JobCount(), 0u);
  store->SetStoreId("abc");
  store->ReserveJobIdsThrough(41);  // before any job: the sequence row is created
  EXPECT_EQ(store->Submit(Spec()), 42u);
  store->ReserveJobIdsThrough(7);   // never lowers it
  EXPECT_EQ(store->Submit(Spec()), 43u);
  store.reset();
  store = Open();
  EXPECT_EQ(store->StoreId(), "abc");
  EXPECT_TRUE(store->HasJob(42));
  EXPECT_FALSE(store->HasJob(41));
  EXPECT_EQ(store->JobCount(), 2u);
}

TEST_F(JobStoreTest, StatsStayAnObject) {
  auto store = Open();
  const uint64_t id = store->Submit(Spec());
  ASSERT_TRUE(store->ClaimNext().has_value());
  ASSERT_TRUE(store->SetStats(id, {{"coherence", 0.5}, {"drop", 1}}));
  EXPECT_TRUE(store->SetStats(id, nullptr));                 // merges nothing
  EXPECT_TRUE(store->SetStats(id, {{"drop", nullptr}}));     // RFC 7386: null removes a key
  EXPECT_THROW(store->SetStats(id, nlohmann::json::array()), std::invalid_argument);
  EXPECT_THROW(store->Complete(id, 3), std::invalid_argument);
  EXPECT_EQ(store->Get(id)->state, JobState::kRunning);  // the refused Complete rolled back
  EXPECT_EQ(store->Get(id)->stats, (nlohmann::json{{"coherence", 0.5}}));
}

void ExpectOpenFailsMentioning(const fs::path& file, const std::string& text) {
  try {
    JobStore store(file);
    FAIL() << "opened " << file;
  } catch (const JobStoreError& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find(file.string()), std::string::npos) << message;
    EXPECT_NE(message.find(text), std::string::npos) << message;
  }
}

TEST_F(JobStoreTest, NonSqliteFileIsRefusedNamingThePath) {
  std::ofstream(file_) << "this is a render log, not a database\n" << std::string(4096, 'x');
  ExpectOpenFailsMentioning(file_, "not a database");
}

TEST_F(JobStoreTest, UnopenablePathIsRefusedNamingThePath) {
  ExpectOpenFailsMentioning(folder_ / "missing-folder" / "jobs.sqlite", "unable to open");
}

TEST_F(JobStoreTest, NewerSchemaIsRefused) {
  Open()->Submit(Spec());
  RawExec(file_, "PRAGMA user_version = 99");
  ExpectOpenFailsMentioning(file_, "schema version 99 is newer");
}

// A file written by schema 1 (no frame size, no motion) opens: its jobs get their frame
// size from their scenes, once, and their motion reads as unknown.
TEST_F(JobStoreTest, SchemaOneFilesGetTheirFrameSizesFromTheirScenes) {
  JobSpec spec = Spec();
  spec.sceneJson = R"({"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]}, "render": {"width": 320, "height": 200}})";
  spec.cameraOrLightsChange = false;
  const uint64_t id = Open()->Submit(spec);
  RawExec(file_,
          "DROP TABLE scene_prices; ALTER TABLE jobs DROP COLUMN deforming_meshes; "
          "DROP TABLE job_events; DROP TABLE job_assets; DROP TABLE job_deletions; DROP INDEX jobs_by_finish; "
          "ALTER TABLE jobs DROP COLUMN width; ALTER TABLE jobs DROP COLUMN height; "
          "ALTER TABLE jobs DROP COLUMN camera_or_lights_change; ALTER TABLE jobs DROP COLUMN plan; "
          "DROP TABLE store_identity; PRAGMA user_version = 1");
  auto store = Open();
  const std::optional<JobRecord> record = store->Get(id);
  ASSERT_TRUE(record.has_value());
  EXPECT_EQ(record->spec.frameSize.width, 320);
  EXPECT_EQ(record->spec.frameSize.height, 200);
  EXPECT_FALSE(record->spec.cameraOrLightsChange.has_value());
  EXPECT_FALSE(record->spec.deformingMeshes.has_value());
  EXPECT_EQ(store->List().at(0).spec.frameSize.width, 320);  // lists need no scene for it
}

TEST_F(JobStoreTest, JobsWithoutAFrameSizeAreRefused) {
  JobSpec spec = Spec();
  spec.frameSize = {0, 6};
  EXPECT_THROW(Open()->Submit(spec), std::invalid_argument);
}

TEST_F(JobStoreTest, NewFileGetsTheCurrentSchemaVersion) {
  Open();
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(file_.string().c_str(), &db), SQLITE_OK);
  sqlite3_stmt* statement = nullptr;
  ASSERT_EQ(sqlite3_prepare_v2(db, "PRAGMA user_version", -1, &statement, nullptr), SQLITE_OK);
  ASSERT_EQ(sqlite3_step(statement), SQLITE_ROW);
  EXPECT_EQ(sqlite3_column_int(statement, 0), JobStore::kSchemaVersion);
  sqlite3_finalize(statement);
  sqlite3_close(db);
}

// --- lists: filters, pages, totals ------------------------------------------------------

TEST_F(JobStoreTest, QueryFiltersPagesAndCountsEveryMatch) {
  auto store = Open();
  std::vector<uint64_t> ids;
  const std::vector<std::pair<std::string, Strategy>> jobs{
      {"Orbit shot", Strategy::kSearch}, {"orbit close-up", Strategy::kExact}, {"teapot", Strategy::kSearch},
      {"ORBIT wide", Strategy::kAuto},   {"fly-through", Strategy::kBrute},   {"orbit again", Strategy::kSearch}};
  for (const auto& [name, strategy] : jobs) {
    JobSpec spec = Spec(0, name);
    spec.strategy = strategy;
    ids.push_back(store->Submit(spec));
  }
  ASSERT_EQ(store->ClaimNext()->id, ids[0]);
  ASSERT_TRUE(store->Fail(ids[0], "broken"));
  ASSERT_TRUE(store->Cancel(ids[2]));

  JobPage all = store->Query({});
  EXPECT_EQ(all.total, 6u);
  ASSERT_EQ(all.records.size(), 6u);
  EXPECT_EQ(all.records.front().id, ids[5]);  // newest first
  // offset really skips; total counts the matches, not the page.
  JobQuery page;
  page.limit = 2;
  page.offset = 2;
  all = store->Query(page);
  EXPECT_EQ(all.total, 6u);
  ASSERT_EQ(all.records.size(), 2u);
  EXPECT_EQ(all.records[0].id, ids[3]);
  EXPECT_EQ(all.records[1].id, ids[2]);
  page.offset = 6;
  EXPECT_TRUE(store->Query(page).records.empty());
  EXPECT_EQ(store->Query(page).total, 6u);

  JobQuery byName;
  byName.nameContains = "orBIT";  // ASCII letters fold either way
  JobPage orbits = store->Query(byName);
  EXPECT_EQ(orbits.total, 4u);
  byName.strategies = {Strategy::kSearch};
  orbits = store->Query(byName);
  ASSERT_EQ(orbits.total, 2u);
  EXPECT_EQ(orbits.records[0].id, ids[5]);
  EXPECT_EQ(orbits.records[1].id, ids[0]);

  JobQuery finished;
  finished.states = {JobState::kFailed, JobState::kCanceled};
  JobPage ended = store->Query(finished);
  ASSERT_EQ(ended.total, 2u);
  EXPECT_EQ(ended.records[0].id, ids[2]);
  EXPECT_EQ(ended.records[1].id, ids[0]);
  finished.nameContains = "%";  // no wildcard: only a name holding a '%' would match
  EXPECT_EQ(store->Query(finished).total, 0u);

  JobQuery autoJobs;
  autoJobs.strategies = {Strategy::kAuto, Strategy::kBrute};
  EXPECT_EQ(store->Query(autoJobs).total, 2u);
}

// A farm that kept every job: a page and its total come from SQL, not from reading every
// record, so they stay fast whatever the stats each finished job carries.
TEST_F(JobStoreTest, QueryStaysFastAmongThousandsOfJobs) {
  auto store = Open();
  constexpr int kJobs = 3000;
  const nlohmann::json stats = {{"analysis", std::string(8 << 10, 'a')}};
  for (int i = 0; i < kJobs; ++i) {
    // The even ones complete: a higher priority makes each the one ClaimNext takes.
    const uint64_t id = store->Submit(Spec(i % 2 == 0 ? 1 : 0, i % 3 == 0 ? "shot " + std::to_string(i) : "test"));
    if (i % 2 == 0) {
      ASSERT_EQ(store->ClaimNext()->id, id);
      ASSERT_TRUE(store->Complete(id, stats));
    }
  }
  JobQuery query;
  query.states = {JobState::kCompleted};
  query.nameContains = "SHOT";
  query.limit = 50;
  query.offset = 400;
  const auto start = std::chrono::steady_clock::now();
  const JobPage page = store->Query(query);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(page.total, 500u);  // i divisible by 6
  ASSERT_EQ(page.records.size(), 50u);
  EXPECT_EQ(page.records[0].spec.name, "shot " + std::to_string(6 * (500 - 401)));
  EXPECT_LT(seconds, 0.25) << "a page among " << kJobs << " jobs took " << seconds << " s";
}

// --- events ------------------------------------------------------------------------------

std::vector<std::string> TypesOf(const std::vector<JobEvent>& events) {
  std::vector<std::string> types;
  for (const JobEvent& event : events) types.push_back(event.type);
  return types;
}

TEST_F(JobStoreTest, EveryTransitionRecordsItsEventInOrder) {
  auto store = Open();
  std::vector<JobEvent> heard;
  store->AddEventListener([&heard](const JobEvent& event) { heard.push_back(event); });
  const uint64_t id = store->Submit(Spec(3, "ball"));
  nowMs_ = 2'000;
  ASSERT_TRUE(store->ClaimNext().has_value());
  for (int frame = 1; frame <= 10; ++frame) ASSERT_TRUE(store->RecordFrame(id, frame, 12, 36));
  nowMs_ = 4'500;
  ASSERT_TRUE(store->Complete(id, {{"wall_seconds", 2.5}}, {{"verification", "3 frames verified", {{"frames", 3}}}}));

  const std::vector<JobEvent> events = store->Events({id, 0, 100});
  EXPECT_EQ(TypesOf(events),
            (std::vector<std::string>{"submitted", "started", "frames_written", "verification", "completed"}));
  for (size_t i = 1; i < events.size(); ++i) EXPECT_GT(events[i].seq, events[i - 1].seq);
  EXPECT_EQ(events[0].timeMs, 1'000);
  EXPECT_EQ(events[0].message, "submitted 'ball': search, frames 1..10, priority 3");
  EXPECT_EQ(events[0].fields["priority"], 3);
  EXPECT_EQ(events[1].message, "started");
  EXPECT_EQ(events[2].message, "frames 1..10 written");
  EXPECT_EQ(events[2].fields["first"], 1);
  EXPECT_EQ(events[2].fields["last"], 10);
  EXPECT_EQ(events[3].fields["frames"], 3);
  EXPECT_EQ(events[4].fields["wall_seconds"], 2.5);
  EXPECT_DOUBLE_EQ(events[4].fields["traced_pixel_ratio"].get<double>(), 12.0 / 48.0);
  EXPECT_EQ(events[4].message, "completed: 10 frames, traced-pixel ratio 0.250, 2.5 s");
  // Listeners heard the same, once each; the log survives a reopen, and `after` pages it.
  ASSERT_EQ(heard.size(), events.size());
  EXPECT_EQ(heard.back().seq, events.back().seq);
  store.reset();
  store = Open();
  EXPECT_EQ(store->Events({id, events[1].seq, 100}).size(), 3u);
  EXPECT_EQ(store->Events({std::nullopt, 0, 2}).size(), 2u);
  EXPECT_EQ(store->LastEventSeq(), events.back().seq);
}

TEST_F(JobStoreTest, FramesWrittenEventsGatherTenFramesOrOneSecond) {
  auto store = Open();
  const uint64_t id = store->Submit(Spec());
  JobSpec longer = Spec();
  longer.lastFrame = 100;
  const uint64_t other = store->Submit(longer);
  ASSERT_TRUE(store->ClaimNext().has_value());
  ASSERT_TRUE(store->ClaimNext().has_value());
  auto framesWritten = [&](uint64_t job) {
    std::vector<JobEvent> events = store->Events({job, 0, 1000});
    events.erase(std::remove_if(events.begin(), events.end(),
                                [](const JobEvent& e) { return e.type != "frames_written"; }),
                 events.end());
    return events;
  };
  // Twenty-five frames at once, out of order: two events of ten, five frames untold.
  for (int frame = 100; frame >= 76; --frame) ASSERT_TRUE(store->RecordFrame(other, frame, 1, 47));
  std::vector<JobEvent> told = framesWritten(other);
  ASSERT_EQ(told.size(), 2u);
  EXPECT_EQ(told[0].message, "frames 91..100 written");
  EXPECT_EQ(told[1].fields["first"], 81);
  // Frames 3, 4, 7: told once a second has passed since the first of them.
  ASSERT_TRUE(store->RecordFrame(id, 3, 1, 47));
  nowMs_ = 1'600;
  ASSERT_TRUE(store->RecordFrame(id, 7, 1, 47));
  ASSERT_TRUE(store->RecordFrame(id, 4, 1, 47));
  store->FlushFrameEvents();
  EXPECT_TRUE(framesWritten(id).empty());
  nowMs_ = 1'999;
  store->FlushFrameEvents();
  EXPECT_TRUE(framesWritten(id).empty());
  nowMs_ = 2'000;
  store->FlushFrameEvents();
  told = framesWritten(id);
  ASSERT_EQ(told.size(), 1u);
  EXPECT_EQ(told[0].message, "3 frames written: 3..4, 7");
  EXPECT_EQ(told[0].fields["ranges"], (nlohmann::json{{3, 4}, {7, 7}}));
  EXPECT_EQ(told[0].fields["count"], 3);
  EXPECT_EQ(framesWritten(other).size(), 3u);  // its five, due as well
  store->FlushFrameEvents();
  EXPECT_EQ(framesWritten(id).size(), 1u);
  // A final transition tells what is untold first: nothing is lost, nothing told twice.
  ASSERT_TRUE(store->RecordFrame(id, 9, 1, 47));
  ASSERT_TRUE(store->Cancel(id));
  const std::vector<JobEvent> events = store->Events({id, 0, 100});
  ASSERT_GE(events.size(), 2u);
  EXPECT_EQ(events[events.size() - 2].message, "frame 9 written");
  EXPECT_EQ(events.back().type, "canceled");
  EXPECT_EQ(events.back().message, "canceled with 4 of 10 frames written");
}

// --- retry, change, delete --------------------------------------------------------------

TEST_F(JobStoreTest, RetryQueuesAFailedOrCanceledJobAgainWithItsFrames) {
  auto store = Open();
  const uint64_t canceled = store->Submit(Spec());
  const uint64_t failed = store->Submit(Spec());
  const uint64_t completed = store->Submit(Spec());
  const uint64_t queued = store->Submit(Spec());
  ASSERT_EQ(store->ClaimNext()->id, canceled);
  ASSERT_TRUE(store->RecordFrame(canceled, 2, 10, 38));
  ASSERT_TRUE(store->SetPlan(canceled, {{"strategy", "search"}, {"bin_width", 10}}));
  nowMs_ = 5'000;
  ASSERT_TRUE(store->Cancel(canceled));
  ASSERT_TRUE(store->Fail(failed, "a worker could not trace it"));
  ASSERT_EQ(store->ClaimNext()->id, completed);
  ASSERT_TRUE(store->Complete(completed, {}));

  EXPECT_FALSE(store->Retry(completed));
  EXPECT_FALSE(store->Retry(queued));
  EXPECT_FALSE(store->Retry(999));
  ASSERT_TRUE(store->Retry(canceled));
  ASSERT_TRUE(store->Retry(failed));
  JobRecord record = *store->Get(canceled);
  EXPECT_EQ(record.state, JobState::kQueued);
  EXPECT_EQ(record.finishedMs, 0);
  EXPECT_EQ(record.startedMs, 1'000);  // as after a restart: the job resumes
  EXPECT_EQ(record.framesDone, 1);
  EXPECT_EQ(record.tracedPerFrame[1], 10);
  EXPECT_EQ(record.plan["bin_width"], 10);
  record = *store->Get(failed);
  EXPECT_EQ(record.state, JobState::kQueued);
  EXPECT_TRUE(record.error.empty());
  const std::vector<JobEvent> events = store->Events({canceled, 0, 100});
  EXPECT_EQ(events.back().type, "retried");
  EXPECT_EQ(events.back().message, "queued again after it was canceled; 1 of 10 frames written are kept");
  EXPECT_EQ(store->Events({failed, 0, 100}).back().fields["previous_state"], "failed");
  EXPECT_FALSE(store->Retry(canceled));  // queued now
  // The oldest queued job goes first, as for any job of its priority.
  EXPECT_EQ(store->ClaimNext()->id, canceled);
  EXPECT_TRUE(store->RecordFrame(canceled, 3, 10, 38));
  EXPECT_FALSE(store->RecordFrame(canceled, 2, 10, 38));  // kept, counted once
}

TEST_F(JobStoreTest, ChangeSetsPriorityAndNameAndTheClaimOrderFollows) {
  auto store = Open();
  const uint64_t older = store->Submit(Spec(0, "a"));
  const uint64_t newer = store->Submit(Spec(0, "b"));
  ASSERT_TRUE(store->Change(older, {-50, std::nullopt}));
  ASSERT_TRUE(store->Change(newer, {std::nullopt, std::string("b, renamed")}));
  ASSERT_TRUE(store->Change(newer, {0, std::string("b, renamed")}));  // nothing changes: no event
  EXPECT_FALSE(store->Change(999, {1, std::nullopt}));
  EXPECT_THROW(store->Change(older, {101, std::nullopt}), std::invalid_argument);
  EXPECT_THROW(store->Change(older, {-101, std::nullopt}), std::invalid_argument);
  EXPECT_EQ(store->Get(older)->spec.priority, -50);
  EXPECT_EQ(store->Get(newer)->spec.name, "b, renamed");
  // A negative priority is lower than 0, whatever the age.
  EXPECT_EQ(store->ClaimNext()->id, newer);
  EXPECT_EQ(store->ClaimNext()->id, older);
  const std::vector<JobEvent> events = store->Events({older, 0, 100});
  ASSERT_EQ(TypesOf(events), (std::vector<std::string>{"submitted", "priority_changed", "started"}));
  EXPECT_EQ(events[1].message, "priority changed from 0 to -50");
  EXPECT_EQ(events[1].fields, (nlohmann::json{{"from", 0}, {"to", -50}}));
  EXPECT_EQ(TypesOf(store->Events({newer, 0, 100})), (std::vector<std::string>{"submitted", "renamed", "started"}));
  // Finished jobs may still be renamed.
  ASSERT_TRUE(store->Complete(newer, {}));
  EXPECT_TRUE(store->Change(newer, {std::nullopt, std::string("final")}));
  EXPECT_EQ(store->Get(newer)->spec.name, "final");
}

TEST_F(JobStoreTest, DeleteRemovesAFinishedJobAndNamesTheAssetsNoOtherJobNames) {
  auto store = Open();
  const std::string shared(64, 'a'), mine(64, 'b'), theirs(64, 'c');
  JobSpec spec = Spec();
  spec.assetHashes = {shared, mine};
  const uint64_t id = store->Submit(spec);
  spec.assetHashes = {shared, theirs};
  const uint64_t other = store->Submit(spec);
  ASSERT_EQ(store->ClaimNext()->id, id);
  ASSERT_TRUE(store->RecordFrame(id, 1, 10, 38));

  DeletedJob deleted = store->Delete(id);
  EXPECT_EQ(deleted.outcome, DeletedJob::Outcome::kActive);
  EXPECT_EQ(deleted.state, JobState::kRunning);
  EXPECT_EQ(store->Delete(other).outcome, DeletedJob::Outcome::kActive);  // queued
  EXPECT_EQ(store->Delete(999).outcome, DeletedJob::Outcome::kNotFound);
  EXPECT_TRUE(store->PendingDeletions().empty());

  ASSERT_TRUE(store->Complete(id, {}));
  deleted = store->Delete(id);
  ASSERT_EQ(deleted.outcome, DeletedJob::Outcome::kDeleted);
  EXPECT_EQ(deleted.state, JobState::kCompleted);
  EXPECT_EQ(deleted.unreferencedAssets, std::vector<std::string>{mine});
  EXPECT_FALSE(store->Get(id).has_value());
  EXPECT_TRUE(store->RecordedFrames(id).empty());
  EXPECT_TRUE(store->Events({id, 0, 100}).empty());
  EXPECT_EQ(store->Delete(id).outcome, DeletedJob::Outcome::kNotFound);
  // Until its files are removed, the job is noted, across a restart.
  store.reset();
  store = Open();
  EXPECT_EQ(store->PendingDeletions(), std::vector<uint64_t>{id});
  store->FinishDeletion(id, {"deleted", "deleted; 1.0 MiB freed", {{"freed_bytes", 1 << 20}}});
  EXPECT_TRUE(store->PendingDeletions().empty());
  const std::vector<JobEvent> last = store->Events({id, 0, 100});
  ASSERT_EQ(TypesOf(last), std::vector<std::string>{"deleted"});
  EXPECT_EQ(last[0].fields["freed_bytes"], 1 << 20);
  EXPECT_EQ(store->AppendEvent(id, {"worker_lost", "late", {}}), 0u);  // nothing else outlives it

  // The shared asset goes with the last job naming it; its id is never handed out again.
  ASSERT_TRUE(store->Fail(other, "no"));
  EXPECT_EQ(store->Delete(other).unreferencedAssets, (std::vector<std::string>{shared, theirs}));
  EXPECT_GT(store->Submit(Spec()), other);
}

TEST_F(JobStoreTest, FinishedJobsComeEarliestFinishedFirst) {
  auto store = Open();
  const uint64_t first = store->Submit(Spec());
  const uint64_t second = store->Submit(Spec());
  const uint64_t third = store->Submit(Spec());
  const uint64_t queued = store->Submit(Spec());
  nowMs_ = 3'000;
  ASSERT_TRUE(store->Cancel(second));
  nowMs_ = 4'000;
  ASSERT_TRUE(store->Fail(third, "x"));
  nowMs_ = 5'000;
  ASSERT_EQ(store->ClaimNext()->id, first);
  ASSERT_TRUE(store->Complete(first, {}));
  EXPECT_EQ(store->FinishedJobs(std::nullopt), (std::vector<uint64_t>{second, third, first}));
  EXPECT_EQ(store->FinishedJobs(4'000), std::vector<uint64_t>{second});
  EXPECT_EQ(store->FinishedJobs(std::nullopt, 2), (std::vector<uint64_t>{second, third}));
  EXPECT_TRUE(store->FinishedJobs(3'000).empty());
  (void)queued;
}

// A file of schema 3 opens: its jobs name the texture assets their scenes use, and it has
// an event log from then on.
TEST_F(JobStoreTest, SchemaThreeFilesNameTheTexturesTheirScenesUse) {
  const std::string texture(64, 'e');
  JobSpec spec = Spec();
  spec.sceneJson = R"({"materials":{"wood":{"diffuse_texture":{"asset":")" + texture + R"("}}}})";
  const uint64_t id = Open()->Submit(spec);
  RawExec(file_,
          "DROP TABLE scene_prices; ALTER TABLE jobs DROP COLUMN deforming_meshes; "
          "DROP TABLE job_events; DROP TABLE job_assets; DROP TABLE job_deletions; DROP INDEX jobs_by_finish; "
          "PRAGMA user_version = 3");
  auto store = Open();
  ASSERT_TRUE(store->Cancel(id));
  EXPECT_EQ(TypesOf(store->Events({id, 0, 10})), std::vector<std::string>{"canceled"});
  EXPECT_EQ(store->Delete(id).unreferencedAssets, std::vector<std::string>{texture});
}

TEST_F(JobStoreTest, NewTransitionsOfAFullDatabaseAreRefusedWhole) {
  auto store = Open();
  const uint64_t id = store->Submit(Spec(0, "before"));
  ASSERT_TRUE(store->Cancel(id));
  JobSpec large = Spec();
  large.sceneJson = "{\"pad\": \"" + std::string(256 << 10, 'x') + "\"}";
  const uint64_t padding = store->Submit(large);
  ASSERT_TRUE(store->Cancel(padding));
  const uint64_t seq = store->LastEventSeq();
  store->CapFilePages(1);
  int refused = 0;
  for (const std::function<void()>& write : std::vector<std::function<void()>>{
           [&] { store->Change(id, {5, std::string(64 << 10, 'n')}); },
           [&] { store->AppendEvent(id, {"worker_lost", std::string(64 << 10, 'm'), {}}); },
       }) {
    try {
      write();
    } catch (const JobStoreFullError&) {
      ++refused;
    }
  }
  EXPECT_EQ(refused, 2);
  EXPECT_EQ(store->LastEventSeq(), seq);
  const JobRecord record = *store->Get(id);
  EXPECT_EQ(record.state, JobState::kCanceled);
  EXPECT_EQ(record.spec.name, "before");
  EXPECT_EQ(record.spec.priority, 0);
  store->CapFilePages(1 << 30);
  EXPECT_TRUE(store->Retry(id));
}

}  // namespace
}  // namespace tcfarm
