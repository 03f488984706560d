// The dispatcher against fake workers (dispatch/fake_worker.h) and a fake clock for
// liveness.
#include "dispatch/dispatcher.h"

#include <gtest/gtest.h>

#include <map>
#include <memory>
#include <thread>

#include "dispatch/fake_worker.h"
#include "wire/zmq_io.h"

namespace tcfarm {
namespace {

const std::string kHash(64, 'a');

class RecordingSink : public DispatchSink {
 public:
  void OnResult(uint64_t jobId, uint64_t plannerTaskId, wire::Result&& result, double) override {
    results.push_back({jobId, plannerTaskId, result.PixelCount()});
  }
  void OnTaskFailed(uint64_t jobId, uint64_t plannerTaskId, const std::string& why) override {
    failures.push_back({jobId, plannerTaskId, why});
  }
  struct Delivered {
    uint64_t jobId, plannerTaskId;
    size_t pixels;
  };
  struct Failed {
    uint64_t jobId, plannerTaskId;
    std::string why;
  };
  std::vector<Delivered> results;
  std::vector<Failed> failures;
};

class DispatcherTest : public ::testing::Test {
 protected:
  DispatcherTest() : dispatcher_("tcp://127.0.0.1:*", clock_) {
    dispatcher_.AddJob(1, 0, 4, 4, kHash, "{\"scene\": 1}");
  }
  // Lets messages cross loopback, then runs the dispatcher a few rounds.
  void Pump(int rounds = 5) {
    for (int i = 0; i < rounds; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
      dispatcher_.Poll(Milliseconds(5), sink_);
    }
  }
  void EnqueueTasks(uint64_t job, int count) {
    for (int i = 0; i < count; ++i) {
      dispatcher_.Enqueue({job, static_cast<uint64_t>(100 + i), 0, PixelSet::Full(16), 0});
    }
  }

  FakeClock clock_;
  zmq::context_t context_;
  Dispatcher dispatcher_;
  RecordingSink sink_;
};

TEST_F(DispatcherTest, CreditLimitsTasksInFlight) {
  FakeWorker worker(context_, dispatcher_.BoundEndpoint(), 2);
  EnqueueTasks(1, 5);
  Pump();
  std::vector<wire::Task> tasks = worker.Tasks();
  ASSERT_EQ(tasks.size(), 2u);
  EXPECT_EQ(dispatcher_.PendingTasks(), 3u);
  EXPECT_EQ(tasks[0].sceneHash, kHash);
  EXPECT_EQ(tasks[0].width, 4u);
  worker.Answer(tasks[0]);
  Pump();
  ASSERT_EQ(sink_.results.size(), 1u);
  EXPECT_EQ(sink_.results[0].plannerTaskId, 100u);
  EXPECT_EQ(sink_.results[0].pixels, 16u);
  EXPECT_EQ(worker.Tasks().size(), 1u);  // one credit back, one more task
}

TEST_F(DispatcherTest, SilentWorkersTasksGoToAnotherWorker) {
  FakeWorker silent(context_, dispatcher_.BoundEndpoint(), 4);
  EnqueueTasks(1, 3);
  Pump();
  ASSERT_EQ(silent.Tasks().size(), 3u);
  FakeWorker healthy(context_, dispatcher_.BoundEndpoint(), 4);
  Pump();
  EXPECT_TRUE(healthy.Tasks().empty());
  clock_.Advance(Milliseconds(3000));
  healthy.Send(wire::Heartbeat{});
  Pump();
  clock_.Advance(Milliseconds(2500));  // silent: 5.5 s; healthy: 2.5 s
  Pump();
  std::vector<wire::Task> moved = healthy.Tasks();
  ASSERT_EQ(moved.size(), 3u);
  EXPECT_EQ(dispatcher_.counters().requeued, 3u);
  EXPECT_EQ(dispatcher_.counters().workersLost, 1u);
  for (const auto& task : moved) healthy.Answer(task);
  Pump();
  EXPECT_EQ(sink_.results.size(), 3u);
  EXPECT_EQ(dispatcher_.InFlightTasks(), 0u);
}

// A coordinator that spends 6 s on something else (finishing a large frame) has not
// heard its workers meanwhile: their messages wait in its socket, so it must not call
// them silent before it has read them. A worker that really is silent is still found.
TEST_F(DispatcherTest, ABusyCoordinatorReadsBeforeItBlamesItsWorkers) {
  FakeWorker worker(context_, dispatcher_.BoundEndpoint(), 4);
  EnqueueTasks(1, 2);
  Pump();
  ASSERT_EQ(worker.Tasks().size(), 2u);
  worker.Send(wire::Heartbeat{});
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  clock_.Advance(Milliseconds(6000));  // busy: nothing read
  dispatcher_.Flush();                 // liveness is checked before reading
  EXPECT_EQ(dispatcher_.counters().workersLost, 0u);
  Pump();                              // reads the heartbeat sent at the start
  EXPECT_EQ(dispatcher_.counters().workersLost, 0u);
  EXPECT_EQ(dispatcher_.InFlightTasks(), 2u);
  clock_.Advance(Milliseconds(6000));  // now it is silent while the coordinator listens
  Pump();
  EXPECT_EQ(dispatcher_.counters().workersLost, 1u);
  EXPECT_EQ(dispatcher_.counters().requeued, 2u);
}

TEST_F(DispatcherTest, ALateDuplicateResultIsIgnored) {
  FakeWorker first(context_, dispatcher_.BoundEndpoint(), 1);
  EnqueueTasks(1, 1);
  Pump();
  std::vector<wire::Task> tasks = first.Tasks();
  ASSERT_EQ(tasks.size(), 1u);
  first.Answer(tasks[0]);
  first.Answer(tasks[0]);
  Pump();
  EXPECT_EQ(sink_.results.size(), 1u);
  EXPECT_EQ(dispatcher_.counters().duplicateResults, 1u);
}

TEST_F(DispatcherTest, AResultOfTheWrongSizeIsNotDelivered) {
  FakeWorker worker(context_, dispatcher_.BoundEndpoint(), 1);
  EnqueueTasks(1, 1);
  Pump();
  wire::Task task = worker.Tasks().at(0);
  wire::Result result;
  result.taskId = task.taskId;
  result.jobId = task.jobId;
  result.frame = task.frame;
  result.rgb.assign(3, 0.0f);  // one pixel instead of 16
  worker.Send(result);
  Pump();
  EXPECT_TRUE(sink_.results.empty());
  EXPECT_EQ(dispatcher_.counters().unexpected, 1u);
  // The pixels are still owed: the task goes out again.
  std::vector<wire::Task> again = worker.Tasks();
  ASSERT_EQ(again.size(), 1u);
  EXPECT_EQ(again[0].taskId, task.taskId);
}

TEST_F(DispatcherTest, MalformedMessagesAreDroppedAndCounted) {
  FakeWorker worker(context_, dispatcher_.BoundEndpoint(), 1);
  worker.SendRaw({"garbage"});
  worker.SendRaw({std::string(1, '\x01'), std::string(1, '\x03'), "\xff\xff", ""});
  worker.SendRaw({std::string(1, '\x07'), std::string(1, '\x01'), "", ""});
  Pump();
  EXPECT_EQ(dispatcher_.counters().malformed, 3u);
  EnqueueTasks(1, 1);
  Pump();
  EXPECT_EQ(worker.Tasks().size(), 1u);  // still serving
}

TEST_F(DispatcherTest, ScenesAreSentOnRequest) {
  FakeWorker worker(context_, dispatcher_.BoundEndpoint(), 1);
  worker.Send(wire::SceneGet{kHash});
  worker.Send(wire::SceneGet{std::string(64, 'b')});
  Pump();
  std::vector<wire::Message> replies = worker.Drain();
  int scenes = 0, errors = 0;
  for (auto& m : replies) {
    if (auto* s = std::get_if<wire::SceneData>(&m)) {
      ++scenes;
      EXPECT_EQ(s->sceneJson, "{\"scene\": 1}");
    }
    errors += std::holds_alternative<wire::Error>(m);
  }
  EXPECT_EQ(scenes, 1);
  EXPECT_EQ(errors, 1);
}

TEST_F(DispatcherTest, AWorkerErrorFailsTheTask) {
  FakeWorker worker(context_, dispatcher_.BoundEndpoint(), 1);
  EnqueueTasks(1, 1);
  Pump();
  wire::Task task = worker.Tasks().at(0);
  worker.Send(wire::Error{task.taskId, kHash, "scene would not build", ""});
  Pump();
  ASSERT_EQ(sink_.failures.size(), 1u);
  EXPECT_EQ(sink_.failures[0].why, "scene would not build");
}

TEST_F(DispatcherTest, HigherPriorityJobsGetALargerShare) {
  dispatcher_.AddJob(2, 2, 4, 4, kHash, "{}");  // weight 3 against job 1's weight 1
  EnqueueTasks(1, 40);
  EnqueueTasks(2, 40);
  FakeWorker worker(context_, dispatcher_.BoundEndpoint(), 1);
  std::map<uint64_t, int> served;
  for (int i = 0; i < 20; ++i) {
    Pump(2);
    for (const auto& task : worker.Tasks()) {
      ++served[task.jobId];
      worker.Answer(task);
    }
  }
  ASSERT_GE(served[1] + served[2], 16);
  EXPECT_NEAR(static_cast<double>(served[2]) / (served[1] + served[2]), 0.75, 0.1);
}

TEST_F(DispatcherTest, RemovedJobsTasksAreForgottenAndCreditReturns) {
  FakeWorker worker(context_, dispatcher_.BoundEndpoint(), 1);
  EnqueueTasks(1, 2);
  Pump();
  wire::Task task = worker.Tasks().at(0);
  dispatcher_.RemoveJob(1);
  EXPECT_EQ(dispatcher_.PendingTasks(), 0u);
  worker.Answer(task);
  Pump();
  EXPECT_TRUE(sink_.results.empty());
  EXPECT_EQ(dispatcher_.registry().workers().begin()->second.FreeCredit(), 1u);
}

// A coordinator that stops closes its socket right after saying goodbye; the goodbye still
// reaches the workers, which would otherwise wait out their whole coordinator timeout.
TEST(DispatcherGoodbye, ReachesWorkersThoughTheSocketClosesAtOnce) {
  FakeClock clock;
  zmq::context_t context;
  auto dispatcher = std::make_unique<Dispatcher>("tcp://127.0.0.1:*", clock);
  FakeWorker worker(context, dispatcher->BoundEndpoint(), 1);
  RecordingSink sink;
  for (int i = 0; i < 100 && dispatcher->registry().workers().empty(); ++i) {
    dispatcher->Poll(Milliseconds(10), sink);
  }
  ASSERT_EQ(dispatcher->registry().workers().size(), 1u);
  dispatcher->SayGoodbye();
  dispatcher.reset();
  bool saidGoodbye = false;
  for (int i = 0; i < 200 && !saidGoodbye; ++i) {
    for (const wire::Message& message : worker.Drain()) {
      saidGoodbye = saidGoodbye || std::holds_alternative<wire::Disconnect>(message);
    }
    if (!saidGoodbye) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  EXPECT_TRUE(saidGoodbye);
}

}  // namespace
}  // namespace tcfarm
