// The farm loop driven step by step: a real job store and dispatcher socket, fake workers
// in this process (tests/support/cpp/fake_worker.h) and a fake clock, so that a worker's silence
// lasts as long as the test says without the test sleeping through it.
#include "coordinator/farm/farm.h"
#include "coordinator/store/frame_finisher.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <functional>
#include <map>
#include <set>
#include <thread>
#include <random>

#include "tests/support/cpp/fake_worker.h"
#include "coordinator/planner/job_memory.h"
#include "proto/frame/frame_io.h"
#include "coordinator/store/frame_store.h"

namespace tcfarm {
namespace {

namespace fs = std::filesystem;

// Each turn waits at most this long for messages; they cross loopback in microseconds.
constexpr Milliseconds kTurnPoll{5};
// Turns before a test gives up: seconds of polling at most, never a hang.
constexpr int kMaxTurns = 400;

// The referee of a farm whose fake workers answer every pixel with one value: it knows
// that value, so the checks it traces (every check, on a one-worker farm) agree.
class ConstantReferee : public Referee {
 public:
  void Ask(Question question) override {
    Answer answer{question.id, std::vector<float>(3 * question.pixels.size(), value), "", 0, 0};
    answers_[{question.jobId, question.purpose}].push_back(std::move(answer));
  }
  std::vector<Answer> TakeAnswers(uint64_t jobId, Purpose purpose) override {
    std::vector<Answer> answers;
    answers.swap(answers_[{jobId, purpose}]);
    return answers;
  }
  float value = 0.5f;

 private:
  std::map<std::pair<uint64_t, Purpose>, std::vector<Answer>> answers_;
};

class FarmTest : public ::testing::Test {
 protected:
  void SetUp() override {
    folder_ = fs::temp_directory_path() /
              ("tcfarm_farm_" + std::to_string(std::random_device()()) + "_" +
               ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(folder_);
    store_ = std::make_unique<JobStore>(folder_ / "jobs.db");
    farm_ = std::make_unique<Farm>(*store_, Options(), clock_);
    clock_.Advance(Milliseconds(1000));  // past the first look for new jobs
  }
  FarmOptions Options() const {
    FarmOptions options;
    options.endpoint = "tcp://127.0.0.1:*";
    options.storeRoot = folder_ / "store";
    options.output.threads = 1;
    options.referee = &referee_;
    return options;
  }
  // The farm again, with these options (of Options()).
  void RestartFarm(const FarmOptions& options) {
    farm_.reset();
    farm_ = std::make_unique<Farm>(*store_, options, clock_);
  }
  // Steps past the next look for new jobs, so that jobs are claimed as memory allows.
  void StepPastAClaim() {
    clock_.Advance(Milliseconds(200));
    farm_->Step(kTurnPoll);
  }
  void TearDown() override {
    farm_.reset();
    fs::remove_all(folder_);
  }

  // A brute-force job of `frames` frames of 4x3 pixels.
  static JobSpec BruteSpec(int frames) {
    JobSpec spec;
    spec.sceneJson = "{}";  // the fake workers never ask for it
    spec.sceneHash = std::string(64, 'b');
    spec.lastFrame = frames - 1;
    spec.strategy = Strategy::kBrute;
    spec.frameSize = {4, 3};
    spec.cameraOrLightsChange = false;
    return spec;
  }
  uint64_t Submit(int frames) { return store_->Submit(BruteSpec(frames)); }
  std::vector<JobEvent> EventsOf(uint64_t id, const std::string& type) const {
    std::vector<JobEvent> events;
    for (JobEvent& event : store_->Events({id, 0, 1000})) {
      if (event.type == type) events.push_back(std::move(event));
    }
    return events;
  }
  JobState StateOf(uint64_t id) const { return store_->Get(id)->state; }

  // Steps the farm, calling `afterTurn` after each step, until it returns true.
  bool TurnUntil(const std::function<bool()>& afterTurn) {
    for (int turn = 0; turn < kMaxTurns; ++turn) {
      farm_->Step(kTurnPoll);
      if (afterTurn()) return true;
    }
    return false;
  }
  // Steps until `id` completes, `worker` answering every task it gets with `value`.
  bool ServeUntilComplete(FakeWorker& worker, uint64_t id, float value = 0.5f) {
    referee_.value = value;
    return TurnUntil([&] {
      for (const wire::Task& task : worker.Tasks()) worker.Answer(task, value);
      return StateOf(id) == JobState::kCompleted;
    });
  }

  fs::path folder_;
  mutable ConstantReferee referee_;  // Options() hands it out
  FakeClock clock_;
  zmq::context_t context_;
  std::unique_ptr<JobStore> store_;
  std::unique_ptr<Farm> farm_;
};

TEST_F(FarmTest, ASmallJobCompletesAndItsFramesAreWritten) {
  FakeWorker worker(context_, farm_->BoundEndpoint(), 4);
  const uint64_t id = Submit(3);
  ASSERT_TRUE(ServeUntilComplete(worker, id, 0.25f)) << ToString(StateOf(id));

  const JobRecord record = *store_->Get(id);
  EXPECT_EQ(record.framesDone, 3);
  EXPECT_EQ(record.tracedPixels, 3u * 12u);  // brute force traces every pixel
  EXPECT_EQ(record.stats["strategy"]["name"], "brute");
  const FrameStore files(folder_ / "store");
  // While the job rendered its frames were written uncompressed and without previews;
  // once no job renders, the finisher compresses them and makes the previews.
  ASSERT_TRUE(TurnUntil([&] { return FrameFinisher::IsFinished(files, id); }));
  for (int frame = 0; frame < 3; ++frame) {
    EXPECT_TRUE(fs::exists(files.FramePath(id, frame, "png"))) << frame;
    EXPECT_EQ(ExrCompressionOf(files.FramePath(id, frame, "exr")), "zip") << frame;
    EXPECT_TRUE(fs::exists(files.MaskPath(id, MaskKind::kTraced, frame))) << frame;
    EXPECT_TRUE(fs::exists(files.MaskPath(id, MaskKind::kChange, frame))) << frame;
    const Image image = ReadImage(files.FramePath(id, frame, "exr"));
    EXPECT_EQ(image.rgb, std::vector<float>(12 * 3, 0.25f)) << frame;  // the worker's values, bit for bit
  }
  EXPECT_EQ(farm_->metrics().framesWritten.Value(), 3);
  EXPECT_EQ(farm_->metrics().tasksRequeued.Value(), 0);
}

TEST_F(FarmTest, ASilentWorkersTasksAreRequeuedAfterTheTimeout) {
  const std::string lostName = "silent";
  FakeWorker silent(context_, farm_->BoundEndpoint(), 4, lostName);
  const uint64_t id = Submit(2);
  size_t held = 0;
  ASSERT_TRUE(TurnUntil([&] {
    held += silent.Tasks().size();  // taken, never answered
    // Every task sent has arrived: one still in the socket would be requeued unseen.
    return held > 0 && farm_->metrics().queueDepth.Value() == 0 &&
           static_cast<double>(held) == farm_->metrics().tasksInFlight.Value();
  }));
  FakeWorker rescuer(context_, farm_->BoundEndpoint(), 4);
  ASSERT_TRUE(TurnUntil([&] { return farm_->metrics().liveWorkers.Value() == 2; }));
  EXPECT_TRUE(rescuer.Tasks().empty());  // nothing left for it while the silent one holds all

  // Just short of the timeout nothing is taken back; just past it, the silent worker's
  // tasks go to the worker that kept talking.
  const Milliseconds timeout = HeartbeatPolicy{}.timeout;
  clock_.Advance(timeout - Milliseconds(1));
  rescuer.Send(wire::Heartbeat{});
  farm_->Step(Milliseconds(1000));  // returns as soon as the heartbeat is in
  EXPECT_EQ(farm_->metrics().tasksRequeued.Value(), 0);
  clock_.Advance(Milliseconds(2));
  rescuer.Send(wire::Heartbeat{});
  farm_->Step(Milliseconds(1000));
  EXPECT_EQ(farm_->metrics().tasksRequeued.Value(), static_cast<double>(held));
  EXPECT_EQ(farm_->metrics().liveWorkers.Value(), 1);

  ASSERT_TRUE(ServeUntilComplete(rescuer, id)) << ToString(StateOf(id));
  EXPECT_EQ(store_->Get(id)->framesDone, 2);
  // The job's log tells of the lost worker and how many of its tasks went back.
  const std::vector<JobEvent> lost = EventsOf(id, "worker_lost");
  ASSERT_EQ(lost.size(), 1u);
  EXPECT_EQ(lost[0].fields["requeued_tasks"], held);
  EXPECT_EQ(lost[0].message, "worker " + lostName + " went silent; " + std::to_string(held) +
                                " of its tasks of this job were requeued");
}

TEST_F(FarmTest, AJobsEventsTellItsStoryInOrder) {
  FakeWorker worker(context_, farm_->BoundEndpoint(), 4);
  JobSpec spec = BruteSpec(12);
  spec.options["verify"] = {{"frames", "all"}};
  const uint64_t id = store_->Submit(spec);
  ASSERT_TRUE(ServeUntilComplete(worker, id));
  std::vector<std::string> types;
  int framesTold = 0;
  for (const JobEvent& event : store_->Events({id, 0, 1000})) {
    if (types.empty() || types.back() != event.type) types.push_back(event.type);
    if (event.type == "frames_written") framesTold += event.fields["count"].get<int>();
  }
  EXPECT_EQ(types, (std::vector<std::string>{"submitted", "started", "frames_written", "verification", "completed"}));
  EXPECT_EQ(framesTold, 12);  // each frame told once
  const std::vector<JobEvent> verified = EventsOf(id, "verification");
  ASSERT_EQ(verified.size(), 1u);
  EXPECT_EQ(verified[0].fields["reference"]["frames_compared"], 12);
  EXPECT_EQ(verified[0].fields["reference"]["pixels_differing"], 0);
}

// Canceled and retried before the farm loop heard of the cancel: the claim finds the old
// run still there, stops it, and the job resumes from the frames it wrote; the cancel
// that arrives afterwards is stale and leaves the new run alone.
TEST_F(FarmTest, ACanceledJobRetriedAtOnceResumesFromItsFrames) {
  FakeWorker worker(context_, farm_->BoundEndpoint(), 1);
  const uint64_t id = Submit(8);
  referee_.value = 0.75f;  // what the worker answers, so the checks agree
  ASSERT_TRUE(TurnUntil([&] {
    for (const wire::Task& task : worker.Tasks()) worker.Answer(task, 0.75f);
    return store_->Get(id)->framesDone >= 3;
  }));
  ASSERT_TRUE(store_->Cancel(id));
  ASSERT_TRUE(store_->Retry(id));
  const int kept = store_->Get(id)->framesDone;
  clock_.Advance(Milliseconds(1000));  // the next step claims it again
  farm_->Step(kTurnPoll);
  EXPECT_EQ(StateOf(id), JobState::kRunning);
  farm_->RequestCancel(id);
  ASSERT_TRUE(ServeUntilComplete(worker, id, 0.75f)) << ToString(StateOf(id));
  const JobRecord record = *store_->Get(id);
  EXPECT_EQ(record.framesDone, 8);
  EXPECT_EQ(record.stats["resumed_frames"], kept);
  const FrameStore files(folder_ / "store");
  for (int frame = 0; frame < 8; ++frame) {
    EXPECT_EQ(ReadImage(files.FramePath(id, frame, "exr")).rgb, std::vector<float>(12 * 3, 0.75f)) << frame;
  }
}

// A running job's new priority reaches the dispatcher. Priorities share the workers only
// while both jobs have tasks waiting (an idle worker takes whatever there is), so the one
// worker here takes a task at a time while both queues are long.
TEST_F(FarmTest, APriorityChangedWhileRunningCountsForTheNextTasks) {
  FakeWorker worker(context_, farm_->BoundEndpoint(), 1);
  const uint64_t low = Submit(40);
  const uint64_t high = Submit(40);
  std::vector<wire::Task> held;
  ASSERT_TRUE(TurnUntil([&] {
    for (wire::Task& task : worker.Tasks()) held.push_back(std::move(task));
    return held.size() == 1 && farm_->metrics().queueDepth.Value() >= 8;
  }));
  ASSERT_TRUE(store_->Change(low, {-100, std::nullopt}));
  farm_->RequestPriority(low, -100);
  farm_->Step(kTurnPoll);
  std::map<uint64_t, int> served;
  for (int round = 0; round < 6; ++round) {
    worker.Answer(held.back());
    held.clear();
    ASSERT_TRUE(TurnUntil([&] {
      for (wire::Task& task : worker.Tasks()) held.push_back(std::move(task));
      return !held.empty();
    }));
    ++served[held.back().jobId];
  }
  // At most the one low task whose turn had come before the change.
  EXPECT_LE(served[low], 1) << served[high] << " tasks of the other job";
}

// Frames the job is working on show in the snapshot, for per-frame state.
TEST_F(FarmTest, TheSnapshotNamesTheFramesBeingTraced) {
  FakeWorker silent(context_, farm_->BoundEndpoint(), 2);
  const uint64_t id = Submit(6);
  std::vector<wire::Task> held;
  ASSERT_TRUE(TurnUntil([&] {
    for (wire::Task& task : silent.Tasks()) held.push_back(std::move(task));
    return held.size() == 2;
  }));
  clock_.Advance(Milliseconds(300));
  farm_->Step(kTurnPoll);
  std::set<int> expected;
  for (const wire::Task& task : held) expected.insert(task.frame);
  const FarmSnapshot snapshot = farm_->Snapshot();
  ASSERT_TRUE(snapshot.tracingFrames.count(id));
  const std::vector<int>& tracing = snapshot.tracingFrames.at(id);
  // Tasks still queued for a worker count too: every held frame is there, and no more
  // frames than the job's live bins hold.
  for (int frame : expected) EXPECT_NE(std::find(tracing.begin(), tracing.end(), frame), tracing.end()) << frame;
  EXPECT_LE(tracing.size(), 6u);
  EXPECT_TRUE(std::is_sorted(tracing.begin(), tracing.end()));
}

// Deleting a job: the farm lets go of it (a run a cancel has not reached, the finisher)
// before the files go; once the loop has stopped it says it cannot promise that.
TEST_F(FarmTest, ReleaseJobStopsItsRunAndAnswersOnlyWhileTheLoopRuns) {
  FakeWorker worker(context_, farm_->BoundEndpoint(), 1);
  const uint64_t id = Submit(20);
  ASSERT_TRUE(TurnUntil([&] {
    for (const wire::Task& task : worker.Tasks()) worker.Answer(task);
    return store_->Get(id)->framesDone >= 2;
  }));
  ASSERT_TRUE(store_->Cancel(id));  // no RequestCancel: the release alone must stop the run
  std::atomic<int> answer{-1};
  std::thread deleter([&] { answer = farm_->ReleaseJob(id) ? 1 : 0; });
  ASSERT_TRUE(TurnUntil([&] { return answer != -1; }));
  deleter.join();
  EXPECT_EQ(answer, 1);
  const int written = store_->Get(id)->framesDone;
  std::error_code ignored;
  fs::remove_all(folder_ / "store" / std::to_string(id), ignored);
  for (int turn = 0; turn < 20; ++turn) {
    for (const wire::Task& task : worker.Tasks()) worker.Answer(task);
    farm_->Step(kTurnPoll);
  }
  EXPECT_FALSE(fs::exists(folder_ / "store" / std::to_string(id)));  // nothing wrote into it again
  EXPECT_EQ(store_->Get(id)->framesDone, written);
  std::atomic<bool> stop{true};
  farm_->Run(stop);
  EXPECT_FALSE(farm_->ReleaseJob(id));
}

// One memory budget for all running jobs: a job claimed takes its share
// (JobMemoryBytes, from its request); one that does not fit in what the running jobs leave
// stays queued, a smaller one behind it that fits passes it, and the waiting one starts
// once memory frees.
TEST_F(FarmTest, JobsAreClaimedAsTheFarmsMemoryAllows) {
  JobSpec big = BruteSpec(10);
  big.frameSize = {64, 64};
  const JobMemoryShape bigShape{64, 64, 10, Strategy::kBrute, 2, false, 0};
  const JobMemoryShape smallShape{4, 3, 1, Strategy::kBrute, 2, false, 0};
  FarmOptions options = Options();
  options.pendingFrameBytes = 0;
  // One big job and the small one fit at once, two big ones do not.
  options.farmMemoryBytes = JobMemoryBytes(bigShape, 1) + JobMemoryBytes(smallShape, 1);
  ASSERT_LT(options.farmMemoryBytes, 2 * JobMemoryBytes(bigShape, 1));
  RestartFarm(options);
  const uint64_t first = store_->Submit(big), second = store_->Submit(big);
  const uint64_t small = Submit(1);
  for (int look = 0; look < 3; ++look) StepPastAClaim();
  EXPECT_EQ(StateOf(first), JobState::kRunning);
  EXPECT_EQ(StateOf(second), JobState::kQueued);
  EXPECT_EQ(StateOf(small), JobState::kRunning);  // passed the big one that waits

  FakeWorker worker(context_, farm_->BoundEndpoint(), 4);
  ASSERT_TRUE(ServeUntilComplete(worker, first));
  StepPastAClaim();
  ASSERT_TRUE(ServeUntilComplete(worker, second)) << ToString(StateOf(second));
}

// A job that waited for memory longer than longestMemoryWait is passed by no later job,
// so that a stream of small jobs cannot keep it waiting forever.
TEST_F(FarmTest, AJobWaitingForMemoryTooLongIsPassedByNoOther) {
  JobSpec big = BruteSpec(10);
  big.frameSize = {64, 64};
  const JobMemoryShape bigShape{64, 64, 10, Strategy::kBrute, 2, false, 0};
  FarmOptions options = Options();
  options.pendingFrameBytes = 0;
  options.farmMemoryBytes = JobMemoryBytes(bigShape, 1) * 3 / 2;
  options.longestMemoryWait = Milliseconds(1000);
  RestartFarm(options);
  const uint64_t first = store_->Submit(big), second = store_->Submit(big);
  StepPastAClaim();
  ASSERT_EQ(StateOf(first), JobState::kRunning);
  ASSERT_EQ(StateOf(second), JobState::kQueued);
  const uint64_t passes = Submit(1);
  StepPastAClaim();
  EXPECT_EQ(StateOf(passes), JobState::kRunning);  // the big one has not waited long yet
  clock_.Advance(Milliseconds(1000));
  const uint64_t waits = Submit(1);
  for (int look = 0; look < 3; ++look) StepPastAClaim();
  EXPECT_EQ(StateOf(waits), JobState::kQueued);
  EXPECT_EQ(StateOf(second), JobState::kQueued);
}

// A job queued before the farm's memory shrank, that no longer fits even alone, does not
// wait forever (holding every job behind it): it starts and fails, saying what it needs.
TEST_F(FarmTest, AJobThatCanNeverFitFailsInsteadOfWaiting) {
  JobSpec big = BruteSpec(10);
  big.frameSize = {64, 64};
  FarmOptions options = Options();
  options.pendingFrameBytes = 0;
  options.farmMemoryBytes = JobMemoryBytes({64, 64, 10, Strategy::kBrute, 2, false, 0}, 1) - 1;
  RestartFarm(options);
  const uint64_t id = store_->Submit(big);
  StepPastAClaim();
  ASSERT_TRUE(TurnUntil([&] { return StateOf(id) == JobState::kFailed; })) << ToString(StateOf(id));
  EXPECT_NE(store_->Get(id)->error.find("for all its running jobs"), std::string::npos) << store_->Get(id)->error;
}

}  // namespace
}  // namespace tcfarm

namespace tcfarm {
namespace {

// Segment prices a previous coordinator measured (in the store) price auto's exact for the
// same scene; another scene of the kind gets the kind's, a scene of the other kind the priors.
TEST_F(FarmTest, AutoPricesExactByTheScenesPricesKeptInTheStore) {
  const std::string skinned(64, 's');
  store_->SaveScenePrices({skinned, true, 3.0, 1.2}, PriceBook::kDefaultCapacity);
  RestartFarm(Options());
  auto submit = [&](const std::string& hash, bool deforming) {
    JobSpec spec = BruteSpec(12);
    spec.strategy = Strategy::kAuto;
    spec.sceneHash = hash;
    spec.deformingMeshes = deforming;
    return store_->Submit(spec);
  };
  const uint64_t same = submit(skinned, true), kind = submit(std::string(64, 't'), true),
                 rigid = submit(std::string(64, 'r'), false);
  clock_.Advance(Milliseconds(1000));
  farm_->Step(kTurnPoll);
  clock_.Advance(Milliseconds(1000));
  farm_->Step(kTurnPoll);
  const FarmSnapshot snapshot = farm_->Snapshot();
  auto exactOf = [&](uint64_t id) {
    const nlohmann::json& strategy = snapshot.runningStats.at(id)["strategy"];
    for (const nlohmann::json& candidate : strategy["candidates"]) {
      if (candidate["strategy"] == "exact") return std::make_pair(strategy["name"], candidate["from"]);
    }
    return std::make_pair(nlohmann::json(), nlohmann::json());
  };
  EXPECT_EQ(exactOf(same), std::make_pair(nlohmann::json("brute"), nlohmann::json("scene")));
  EXPECT_EQ(exactOf(kind).second, "farm");
  EXPECT_EQ(exactOf(kind).first, "brute");  // the kind's prices: dear as well
  EXPECT_EQ(exactOf(rigid), std::make_pair(nlohmann::json("exact"), nlohmann::json("prior")));
}

}  // namespace
}  // namespace tcfarm
