// The dispatcher against fake workers (tests/support/cpp/fake_worker.h) and a fake clock for
// liveness.
#include "coordinator/dispatch/dispatcher.h"

#include <gtest/gtest.h>

#include <functional>

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "tests/support/cpp/fake_worker.h"
#include "proto/wire/content_hash.h"
#include "proto/wire/zmq_io.h"

namespace tcfarm {
namespace {

const std::string kHash(64, 'a');

class RecordingSink : public DispatchSink {
 public:
  void OnResult(const DispatchTask& task, wire::Result&& result, double, const WorkerState&) override {
    results.push_back({task.jobId, task.plannerTaskId, result.PixelCount()});
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
  // Polls until `done` holds, for at most 10 s: messages cross real sockets, and a loaded
  // machine may take longer than a few polls to connect a worker.
  void PumpUntil(const std::function<bool()>& done) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    do {
      Pump(1);
    } while (!done() && std::chrono::steady_clock::now() < deadline);
  }
  // Pumps until `count` workers are registered (at most 10 s).
  void PumpUntilWorkers(size_t count) {
    PumpUntil([&] { return dispatcher_.registry().workers().size() >= count; });
  }
  // Pumps until `worker` has got `count` tasks (at most 10 s), then a few rounds more, so that
  // a task too many shows too; every task it got. A task sent in a poll's last turn is still
  // crossing the sockets when that poll returns, so one look at the worker is not enough.
  std::vector<wire::Task> TasksFor(FakeWorker& worker, size_t count) {
    std::vector<wire::Task> tasks;
    const auto take = [&] {
      for (auto& task : worker.Tasks()) tasks.push_back(std::move(task));
    };
    PumpUntil([&] {
      take();
      return tasks.size() >= count;
    });
    Pump();
    take();
    return tasks;
  }
  // Pumps until some worker was heard at the fake clock's present (at most 10 s): its
  // heartbeat was read before the clock moves on.
  void PumpUntilHeardNow() {
    PumpUntil([&] {
      for (const auto& [identity, worker] : dispatcher_.registry().workers()) {
        if (worker.lastHeard == clock_.Now()) return true;
      }
      return false;
    });
  }
  // A fresh worker connects, takes the tasks still owed and answers them; how many it got.
  size_t AnotherWorkerFinishesWhatIsOwed() {
    const size_t owedCount = dispatcher_.PendingTasks();
    FakeWorker honest(context_, dispatcher_.BoundEndpoint(), 2);
    std::vector<wire::Task> owed;
    PumpUntil([&] {
      for (auto& task : honest.Tasks()) owed.push_back(std::move(task));
      return owed.size() >= owedCount;
    });
    const size_t resultsBefore = sink_.results.size();
    for (const auto& task : owed) honest.Answer(task);
    PumpUntil([&] { return sink_.results.size() >= resultsBefore + owed.size(); });
    return owed.size();
  }
  // `worker` answers every task it gets until it has answered `count` (for at most 10 s): how
  // many it served of each job.
  std::map<uint64_t, int> Serve(FakeWorker& worker, int count) {
    std::map<uint64_t, int> served;
    int total = 0;
    PumpUntil([&] {
      for (const auto& task : worker.Tasks()) {
        ++served[task.jobId];
        ++total;
        worker.Answer(task);
      }
      return total >= count;
    });
    return served;
  }
  void EnqueueTasks(uint64_t job, int count) {
    for (int i = 0; i < count; ++i) {
      dispatcher_.Enqueue({job, static_cast<uint64_t>(100 + i), 0, PixelSet::Full(16), 0, {}});
    }
  }

  FakeClock clock_;
  zmq::context_t context_;
  Dispatcher dispatcher_;
  RecordingSink sink_;
};

// A check goes to a worker other than the one whose values it checks, by principal: a
// check by the worker it checks proves nothing. With nobody else present it is handed
// back to be traced elsewhere (the referee), never given to the worker it avoids.
TEST_F(DispatcherTest, ATaskNeverGoesToAWorkerItAvoids) {
  FakeWorker checked(context_, dispatcher_.BoundEndpoint(), 4);
  PumpUntilWorkers(1);
  ASSERT_EQ(dispatcher_.registry().workers().size(), 1u);
  const std::string principal = dispatcher_.registry().workers().begin()->second.principal;
  EXPECT_EQ(principal.rfind("name:fake-", 0), 0u) << principal;
  DispatchTask check{1, 100, 0, PixelSet::Full(16), 0, {principal}, /*refereeMayTrace=*/true};
  DispatchTask plannerTask{1, 99, 0, PixelSet::Full(16), 0, {principal}, /*refereeMayTrace=*/false};
  dispatcher_.Enqueue(check);
  dispatcher_.Enqueue(plannerTask);
  Pump();
  EXPECT_TRUE(checked.Tasks().empty());  // it had credit to spare, yet got neither
  const std::vector<DispatchTask> stranded = dispatcher_.TakeStranded();
  ASSERT_EQ(stranded.size(), 1u);  // the check, not the planner's task
  EXPECT_EQ(stranded[0].plannerTaskId, 100u);
  EXPECT_EQ(dispatcher_.PendingTasks(), 1u);
  FakeWorker other(context_, dispatcher_.BoundEndpoint(), 4);
  PumpUntilWorkers(2);
  ASSERT_EQ(dispatcher_.registry().workers().size(), 2u);
  for (uint64_t id = 101; id < 104; ++id) dispatcher_.Enqueue({1, id, 0, PixelSet::Full(16), 0, {principal}, true});
  EXPECT_TRUE(dispatcher_.TakeStranded().empty());  // someone else may take them now
  EXPECT_EQ(TasksFor(other, 4).size(), 4u);  // the three checks and the waiting planner task
  EXPECT_TRUE(checked.Tasks().empty());
}

TEST_F(DispatcherTest, CreditLimitsTasksInFlight) {
  FakeWorker worker(context_, dispatcher_.BoundEndpoint(), 2);
  EnqueueTasks(1, 5);
  std::vector<wire::Task> tasks = TasksFor(worker, 2);
  ASSERT_EQ(tasks.size(), 2u);
  EXPECT_EQ(dispatcher_.PendingTasks(), 3u);
  EXPECT_EQ(tasks[0].sceneHash, kHash);
  EXPECT_EQ(tasks[0].width, 4u);
  worker.Answer(tasks[0]);
  const std::vector<wire::Task> more = TasksFor(worker, 1);
  ASSERT_EQ(sink_.results.size(), 1u);
  EXPECT_EQ(sink_.results[0].plannerTaskId, 100u);
  EXPECT_EQ(sink_.results[0].pixels, 16u);
  EXPECT_EQ(more.size(), 1u);  // one credit back, one more task
}

TEST_F(DispatcherTest, SilentWorkersTasksGoToAnotherWorker) {
  FakeWorker silent(context_, dispatcher_.BoundEndpoint(), 4);
  EnqueueTasks(1, 3);
  ASSERT_EQ(TasksFor(silent, 3).size(), 3u);
  FakeWorker healthy(context_, dispatcher_.BoundEndpoint(), 4);
  PumpUntilWorkers(2);
  Pump();
  EXPECT_TRUE(healthy.Tasks().empty());
  clock_.Advance(Milliseconds(3000));
  healthy.Send(wire::Heartbeat{});
  PumpUntilHeardNow();
  clock_.Advance(Milliseconds(2500));  // silent: 5.5 s; healthy: 2.5 s
  std::vector<wire::Task> moved = TasksFor(healthy, 3);
  ASSERT_EQ(moved.size(), 3u);
  EXPECT_EQ(dispatcher_.counters().requeued, 3u);
  EXPECT_EQ(dispatcher_.counters().workersLost, 1u);
  for (const auto& task : moved) healthy.Answer(task);
  PumpUntil([&] { return sink_.results.size() >= 3; });
  EXPECT_EQ(sink_.results.size(), 3u);
  EXPECT_EQ(dispatcher_.InFlightTasks(), 0u);
}

// A coordinator that spends 6 s on something else (finishing a large frame) has not
// heard its workers meanwhile: their messages wait in its socket, so it must not call
// them silent before it has read them. A worker that really is silent is still found.
TEST_F(DispatcherTest, ABusyCoordinatorReadsBeforeItBlamesItsWorkers) {
  FakeWorker worker(context_, dispatcher_.BoundEndpoint(), 4);
  EnqueueTasks(1, 2);
  ASSERT_EQ(TasksFor(worker, 2).size(), 2u);
  worker.Send(wire::Heartbeat{});
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  clock_.Advance(Milliseconds(6000));  // busy: nothing read
  dispatcher_.Flush();                 // liveness is checked before reading
  EXPECT_EQ(dispatcher_.counters().workersLost, 0u);
  // Reads the heartbeat sent at the start, waiting for it if it is still on its way (a
  // poll that found nothing would take the worker for silent).
  dispatcher_.Receive(Milliseconds(10000), sink_);
  Pump();
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
  std::vector<wire::Task> tasks = TasksFor(first, 1);
  ASSERT_EQ(tasks.size(), 1u);
  first.Answer(tasks[0]);
  first.Answer(tasks[0]);
  PumpUntil([&] { return dispatcher_.counters().duplicateResults >= 1; });
  EXPECT_EQ(sink_.results.size(), 1u);
  EXPECT_EQ(dispatcher_.counters().duplicateResults, 1u);
}

// Whether the worker is told DISCONNECT; called once the dispatcher has sent it, this waits
// (at most 10 s) for it to cross the sockets.
bool SaidDisconnect(FakeWorker& worker) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  do {
    for (const wire::Message& message : worker.Drain()) {
      if (std::holds_alternative<wire::Disconnect>(message)) return true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  } while (std::chrono::steady_clock::now() < deadline);
  return false;
}

// A worker that answers its own task wrongly cannot be trusted with the others either: it
// is forgotten and told DISCONNECT, and everything it held goes to another worker.
TEST_F(DispatcherTest, AResultOfTheWrongSizeDropsTheWorker) {
  FakeWorker worker(context_, dispatcher_.BoundEndpoint(), 2);
  EnqueueTasks(1, 2);
  std::vector<wire::Task> tasks = TasksFor(worker, 2);
  ASSERT_EQ(tasks.size(), 2u);
  wire::Result result;
  result.taskId = tasks[0].taskId;
  result.jobId = tasks[0].jobId;
  result.frame = tasks[0].frame;
  result.rgb.assign(3, 0.0f);  // one pixel instead of 16
  worker.Send(result);
  PumpUntil([&] { return dispatcher_.counters().workersDropped >= 1; });
  EXPECT_TRUE(sink_.results.empty());
  EXPECT_EQ(dispatcher_.counters().workersDropped, 1u);
  EXPECT_TRUE(dispatcher_.registry().workers().empty());
  EXPECT_TRUE(SaidDisconnect(worker));
  EXPECT_EQ(dispatcher_.PendingTasks(), 2u);  // the pixels are still owed
  EXPECT_EQ(AnotherWorkerFinishesWhatIsOwed(), 2u);
  EXPECT_EQ(sink_.results.size(), 2u);
}

// A worker found returning wrong values is banned: its tasks go to others, and whatever
// it sends afterwards, READY included, is not heard, on this connection or a new one.
TEST_F(DispatcherTest, ADistrustedWorkerIsNeverHeardAgain) {
  FakeWorker liar(context_, dispatcher_.BoundEndpoint(), 2, "liar");
  EnqueueTasks(1, 2);
  const std::vector<wire::Task> held = TasksFor(liar, 2);
  ASSERT_EQ(held.size(), 2u);
  const std::string principal = dispatcher_.registry().workers().begin()->second.principal;
  EXPECT_TRUE(dispatcher_.Distrust(principal, "its values are not the referee's"));
  EXPECT_FALSE(dispatcher_.Distrust(principal, "again"));
  EXPECT_EQ(dispatcher_.counters().workersDistrusted, 1u);
  EXPECT_TRUE(dispatcher_.registry().workers().empty());
  EXPECT_EQ(dispatcher_.PendingTasks(), 2u);
  liar.Answer(held[0]);         // too late: not its task any more
  liar.Send(wire::Ready{2, 1, "liar"});  // and it may not come back
  FakeWorker reconnected(context_, dispatcher_.BoundEndpoint(), 2, "liar");  // nor on a new connection
  PumpUntil([&] {
    return dispatcher_.counters().distrustedMessages >= 2 && dispatcher_.counters().bannedReconnects >= 1;
  });
  EXPECT_TRUE(sink_.results.empty());
  EXPECT_TRUE(dispatcher_.registry().workers().empty());
  EXPECT_GE(dispatcher_.counters().distrustedMessages, 2u);
  EXPECT_EQ(dispatcher_.counters().bannedReconnects, 1u);
  EXPECT_TRUE(reconnected.Tasks().empty());
  EXPECT_EQ(AnotherWorkerFinishesWhatIsOwed(), 2u);
  EXPECT_EQ(sink_.results.size(), 2u);
}

// A ban an operator lifts lets the worker in on its next connection.
TEST_F(DispatcherTest, ALiftedBanLetsTheWorkerBackIn) {
  dispatcher_.Ban("name:liar@127.0.0.1");
  FakeWorker banned(context_, dispatcher_.BoundEndpoint(), 2, "liar");
  PumpUntil([&] { return dispatcher_.counters().bannedReconnects >= 1; });
  EXPECT_EQ(dispatcher_.counters().bannedReconnects, 1u);
  EXPECT_TRUE(dispatcher_.registry().workers().empty());
  EXPECT_TRUE(dispatcher_.Unban("name:liar@127.0.0.1"));
  EXPECT_FALSE(dispatcher_.Unban("name:liar@127.0.0.1"));
  FakeWorker back(context_, dispatcher_.BoundEndpoint(), 2, "liar");
  PumpUntilWorkers(1);
  Pump();
  EXPECT_EQ(dispatcher_.registry().workers().size(), 1u);
}


TEST_F(DispatcherTest, HorizonsOutsideTheWindowDropTheWorker) {
  FakeWorker worker(context_, dispatcher_.BoundEndpoint(), 1);
  dispatcher_.Enqueue({1, 100, 10, PixelSet::Full(16), 4, {}});  // horizons 11 .. 15 are valid
  wire::Task task = TasksFor(worker, 1).at(0);
  wire::Result result;
  result.taskId = task.taskId;
  result.jobId = task.jobId;
  result.frame = task.frame;
  result.rgb.assign(16 * 3, 0.5f);
  result.horizons.assign(16, 15);
  result.horizons[7] = 16;  // one frame beyond the window
  worker.Send(result);
  PumpUntil([&] { return dispatcher_.counters().workersDropped >= 1; });
  EXPECT_TRUE(sink_.results.empty());
  EXPECT_EQ(dispatcher_.counters().workersDropped, 1u);
  EXPECT_TRUE(SaidDisconnect(worker));
}

// A probe that said READY and answers task ids it never got (the ids are sequential, so
// easy to guess) settles nothing: a task's reply counts only from the worker holding it.
TEST_F(DispatcherTest, RepliesFromAnotherWorkerAreDroppedAndCounted) {
  FakeWorker honest(context_, dispatcher_.BoundEndpoint(), 2);
  EnqueueTasks(1, 2);
  std::vector<wire::Task> tasks = TasksFor(honest, 2);
  ASSERT_EQ(tasks.size(), 2u);
  FakeWorker rogue(context_, dispatcher_.BoundEndpoint(), 4);
  PumpUntilWorkers(2);
  rogue.Answer(tasks[0], 0.25f);
  rogue.Send(wire::Error{tasks[1].taskId, kHash, "guessed", ""});
  PumpUntil([&] { return dispatcher_.counters().foreignReplies >= 2; });
  EXPECT_TRUE(sink_.results.empty());
  EXPECT_TRUE(sink_.failures.empty());
  EXPECT_EQ(dispatcher_.counters().foreignReplies, 2u);
  EXPECT_EQ(dispatcher_.InFlightTasks(), 2u);
  EXPECT_EQ(dispatcher_.counters().workersDropped, 0u);  // not its task: nothing to judge it by
  for (const auto& task : tasks) honest.Answer(task);
  PumpUntil([&] { return sink_.results.size() >= 2; });
  EXPECT_EQ(sink_.results.size(), 2u);
  EXPECT_TRUE(rogue.Tasks().empty());
}

// A worker taken for dead whose answer comes after all: its task is another worker's now,
// and only that worker's answer counts (both would be the same bits anyway).
TEST_F(DispatcherTest, ALateResultFromAnExpiredWorkerIsIgnored) {
  FakeWorker slow(context_, dispatcher_.BoundEndpoint(), 1);
  EnqueueTasks(1, 1);
  wire::Task task = TasksFor(slow, 1).at(0);
  FakeWorker other(context_, dispatcher_.BoundEndpoint(), 1);
  PumpUntilWorkers(2);
  clock_.Advance(Milliseconds(3000));
  other.Send(wire::Heartbeat{});
  PumpUntilHeardNow();
  clock_.Advance(Milliseconds(2500));  // slow: 5.5 s of silence
  std::vector<wire::Task> moved = TasksFor(other, 1);
  ASSERT_EQ(moved.size(), 1u);
  slow.Answer(task);
  PumpUntil([&] { return dispatcher_.counters().foreignReplies >= 1; });
  EXPECT_TRUE(sink_.results.empty());
  EXPECT_EQ(dispatcher_.counters().foreignReplies, 1u);
  EXPECT_TRUE(SaidDisconnect(slow));  // it is unknown now: told to start afresh
  other.Answer(moved[0]);
  PumpUntil([&] { return !sink_.results.empty(); });
  EXPECT_EQ(sink_.results.size(), 1u);
}

TEST_F(DispatcherTest, MalformedMessagesFromAStrangerAreDroppedAndCounted) {
  FakeWorker worker(context_, dispatcher_.BoundEndpoint(), 1);
  zmq::socket_t stranger(context_, zmq::socket_type::dealer);
  stranger.connect(dispatcher_.BoundEndpoint());
  for (const std::vector<std::string>& parts :
       {std::vector<std::string>{"garbage"},
        {std::string(1, '\x01'), std::string(1, '\x03'), "\xff\xff", ""},
        {std::string(1, '\x07'), std::string(1, '\x01'), "", ""}}) {
    for (size_t i = 0; i < parts.size(); ++i) {
      stranger.send(zmq::buffer(parts[i]), i + 1 < parts.size() ? zmq::send_flags::sndmore : zmq::send_flags::none);
    }
  }
  PumpUntil([&] { return dispatcher_.counters().malformed == 3; });
  EXPECT_EQ(dispatcher_.counters().malformed, 3u);
  EXPECT_EQ(dispatcher_.counters().workersDropped, 0u);
  EnqueueTasks(1, 1);
  EXPECT_EQ(TasksFor(worker, 1).size(), 1u);  // the worker is still served
}

TEST_F(DispatcherTest, AWorkerThatSendsAMalformedResultLosesItsTasksToAnother) {
  FakeWorker broken(context_, dispatcher_.BoundEndpoint(), 1);
  EnqueueTasks(1, 1);
  const wire::Task task = TasksFor(broken, 1).at(0);
  // Its answer, with the header cut short: refused before its task id can be read.
  wire::Result answer;
  answer.taskId = task.taskId, answer.jobId = task.jobId, answer.frame = task.frame;
  answer.rgb.assign(3 * task.pixels.size(), 0.5f);
  std::vector<std::string> parts = wire::Encode(answer);
  parts[2].resize(parts[2].size() / 2);
  broken.SendRaw(parts);
  FakeWorker other(context_, dispatcher_.BoundEndpoint(), 1);
  std::vector<wire::Task> moved;
  PumpUntil([&] {
    for (auto& t : other.Tasks()) moved.push_back(std::move(t));
    return !moved.empty();
  });
  EXPECT_EQ(dispatcher_.counters().malformed, 1u);
  EXPECT_EQ(dispatcher_.counters().workersDropped, 1u);
  EXPECT_TRUE(SaidDisconnect(broken));
  ASSERT_EQ(moved.size(), 1u);
  EXPECT_EQ(moved[0].taskId, task.taskId);
  other.Answer(moved[0]);
  PumpUntil([&] { return !sink_.results.empty(); });
  EXPECT_EQ(sink_.results.size(), 1u);
}

TEST_F(DispatcherTest, ScenesAreSentOnRequest) {
  FakeWorker worker(context_, dispatcher_.BoundEndpoint(), 1);
  worker.Send(wire::SceneGet{kHash});
  worker.Send(wire::SceneGet{std::string(64, 'b')});
  std::vector<wire::Message> replies;
  PumpUntil([&] {
    for (auto& m : worker.Drain()) replies.push_back(std::move(m));
    size_t answers = 0;  // not counting the dispatcher's heartbeats
    for (auto& m : replies) {
      answers += std::holds_alternative<wire::SceneData>(m) || std::holds_alternative<wire::Error>(m);
    }
    return answers >= 2;
  });
  Pump();
  for (auto& m : worker.Drain()) replies.push_back(std::move(m));
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

TEST_F(DispatcherTest, OneWorkersErrorSendsTheTaskToAnotherAndASecondFailsIt) {
  FakeWorker first(context_, dispatcher_.BoundEndpoint(), 1);
  EnqueueTasks(1, 2);
  wire::Task task = TasksFor(first, 1).at(0);
  first.Send(wire::Error{task.taskId, kHash, "disk full", ""});
  // The only worker gets the job's other task, never the one it failed.
  std::vector<wire::Task> next = TasksFor(first, 1);
  EXPECT_TRUE(sink_.failures.empty());
  EXPECT_EQ(dispatcher_.counters().taskErrorsRetried, 1u);
  ASSERT_EQ(next.size(), 1u);
  EXPECT_NE(next[0].taskId, task.taskId);
  first.Answer(next[0]);
  PumpUntil([&] { return !sink_.results.empty(); });
  Pump();
  EXPECT_EQ(sink_.results.size(), 1u);
  EXPECT_TRUE(first.Tasks().empty());
  EXPECT_EQ(dispatcher_.PendingTasks(), 1u);  // waits for a different worker
  FakeWorker second(context_, dispatcher_.BoundEndpoint(), 1);
  std::vector<wire::Task> retried = TasksFor(second, 1);
  ASSERT_EQ(retried.size(), 1u);
  EXPECT_EQ(retried[0].taskId, task.taskId);
  second.Send(wire::Error{task.taskId, kHash, "scene would not build", ""});
  PumpUntil([&] { return !sink_.failures.empty(); });
  ASSERT_EQ(sink_.failures.size(), 1u);
  EXPECT_EQ(sink_.failures[0].plannerTaskId, 100u);
  EXPECT_EQ(sink_.failures[0].why, "disk full; on another worker: scene would not build");
  EXPECT_EQ(dispatcher_.counters().tasksFailed, 1u);
}

TEST_F(DispatcherTest, ATaskRetriedElsewhereCompletesThere) {
  FakeWorker failing(context_, dispatcher_.BoundEndpoint(), 1);
  FakeWorker honest(context_, dispatcher_.BoundEndpoint(), 1);
  EnqueueTasks(1, 6);
  PumpUntil([&] {
    for (const auto& task : failing.Tasks()) failing.Send(wire::Error{task.taskId, kHash, "broken", ""});
    for (const auto& task : honest.Tasks()) honest.Answer(task);
    return sink_.results.size() >= 6;
  });
  EXPECT_EQ(sink_.results.size(), 6u);
  EXPECT_TRUE(sink_.failures.empty());
  EXPECT_GE(dispatcher_.counters().taskErrorsRetried, 1u);
}

TEST_F(DispatcherTest, HigherPriorityJobsGetALargerShare) {
  dispatcher_.AddJob(2, 2, 4, 4, kHash, "{}");  // weight 3 against job 1's weight 1
  EnqueueTasks(1, 40);
  EnqueueTasks(2, 40);
  FakeWorker worker(context_, dispatcher_.BoundEndpoint(), 1);
  std::map<uint64_t, int> served = Serve(worker, 20);
  ASSERT_GE(served[1] + served[2], 16);
  EXPECT_NEAR(static_cast<double>(served[2]) / (served[1] + served[2]), 0.75, 0.1);
}

// Every priority of the documented range counts: a job of -50 gets one task for every 51
// a job of 0 gets. Once the weight ignored negative priorities, and both got half.
TEST_F(DispatcherTest, NegativePrioritiesGetSmallerSharesThanZero) {
  EXPECT_LT(Dispatcher::WeightOf(-100), Dispatcher::WeightOf(-99));
  EXPECT_LT(Dispatcher::WeightOf(-1), Dispatcher::WeightOf(0));
  EXPECT_DOUBLE_EQ(Dispatcher::WeightOf(0) / Dispatcher::WeightOf(-50), 51.0);
  EXPECT_DOUBLE_EQ(Dispatcher::WeightOf(100) / Dispatcher::WeightOf(0), Dispatcher::WeightOf(0) / Dispatcher::WeightOf(-100));
  dispatcher_.AddJob(2, -50, 4, 4, kHash, "{}");
  EnqueueTasks(2, 40);  // the low job's tasks wait first
  EnqueueTasks(1, 40);
  FakeWorker worker(context_, dispatcher_.BoundEndpoint(), 1);
  std::map<uint64_t, int> served = Serve(worker, 30);
  ASSERT_GE(served[1], 20);
  EXPECT_LE(served[2], 1) << served[1] << " tasks of priority 0";
}

// A running job's priority changes what it gets from its next task on.
TEST_F(DispatcherTest, APriorityChangedWhileTheJobRunsCountsAtOnce) {
  dispatcher_.AddJob(2, 0, 4, 4, kHash, "{}");
  EnqueueTasks(1, 40);
  EnqueueTasks(2, 40);
  FakeWorker worker(context_, dispatcher_.BoundEndpoint(), 1);
  std::map<uint64_t, int> served = Serve(worker, 10);
  EXPECT_NEAR(served[1], served[2], 2);  // equal shares
  dispatcher_.SetPriority(1, -100);
  served = Serve(worker, 20);
  ASSERT_GE(served[2], 15);
  EXPECT_LE(served[1], 1);
}

// Whoever is told of a lost worker learns how many tasks of each job went back.
TEST_F(DispatcherTest, ALostWorkersTasksAreCountedByJob) {
  dispatcher_.AddJob(2, 0, 4, 4, kHash, "{}");
  // One that leaves holding nothing is not news.
  FakeWorker idle(context_, dispatcher_.BoundEndpoint(), 1);
  PumpUntilWorkers(1);
  ASSERT_EQ(dispatcher_.registry().workers().size(), 1u);
  idle.Send(wire::Disconnect{});
  PumpUntil([&] { return dispatcher_.registry().workers().empty(); });
  ASSERT_TRUE(dispatcher_.registry().workers().empty());
  EXPECT_TRUE(dispatcher_.TakeWorkerLosses().empty());
  FakeWorker silent(context_, dispatcher_.BoundEndpoint(), 5);
  EnqueueTasks(1, 3);
  EnqueueTasks(2, 2);
  ASSERT_EQ(TasksFor(silent, 5).size(), 5u);
  EXPECT_TRUE(dispatcher_.TakeWorkerLosses().empty());
  clock_.Advance(Milliseconds(6000));
  Pump();
  const std::vector<WorkerLoss> losses = dispatcher_.TakeWorkerLosses();
  ASSERT_EQ(losses.size(), 1u);
  EXPECT_EQ(losses[0].why, "went silent");
  EXPECT_EQ(losses[0].requeuedTasks, (std::map<uint64_t, size_t>{{1, 3}, {2, 2}}));
  EXPECT_TRUE(dispatcher_.TakeWorkerLosses().empty());
  // One that says goodbye with tasks in hand is lost too.
  FakeWorker leaving(context_, dispatcher_.BoundEndpoint(), 5);
  ASSERT_EQ(TasksFor(leaving, 5).size(), 5u);
  leaving.Send(wire::Disconnect{});
  PumpUntil([&] { return dispatcher_.registry().workers().empty(); });
  const std::vector<WorkerLoss> left = dispatcher_.TakeWorkerLosses();
  ASSERT_EQ(left.size(), 1u);
  EXPECT_EQ(left[0].why, "left");
  EXPECT_EQ(left[0].requeuedTasks, (std::map<uint64_t, size_t>{{1, 3}, {2, 2}}));
}

TEST_F(DispatcherTest, RemovedJobsTasksAreForgottenAndCreditReturns) {
  FakeWorker worker(context_, dispatcher_.BoundEndpoint(), 1);
  EnqueueTasks(1, 2);
  wire::Task task = TasksFor(worker, 1).at(0);
  dispatcher_.RemoveJob(1);
  EXPECT_EQ(dispatcher_.PendingTasks(), 0u);
  worker.Answer(task);
  PumpUntil([&] { return dispatcher_.counters().duplicateResults >= 1; });  // its job is gone
  EXPECT_TRUE(sink_.results.empty());
  EXPECT_EQ(dispatcher_.registry().workers().begin()->second.FreeCredit(), 1u);
}

// The ERRORs naming a scene among a worker's messages.
std::vector<wire::Error> SceneErrors(FakeWorker& worker) {
  std::vector<wire::Error> errors;
  for (auto& message : worker.Drain()) {
    if (auto* error = std::get_if<wire::Error>(&message); error && !error->sceneHash.empty()) errors.push_back(*error);
  }
  return errors;
}

TEST_F(DispatcherTest, WorkersHoldingARemovedJobsTasksAreToldItsSceneIsNoLongerUsed) {
  FakeWorker holder(context_, dispatcher_.BoundEndpoint(), 1);
  EnqueueTasks(1, 1);
  ASSERT_EQ(TasksFor(holder, 1).size(), 1u);
  FakeWorker idle(context_, dispatcher_.BoundEndpoint(), 1);
  PumpUntilWorkers(2);
  dispatcher_.RemoveJob(1);
  std::vector<wire::Error> errors;
  PumpUntil([&] {
    for (auto& error : SceneErrors(holder)) errors.push_back(std::move(error));
    return !errors.empty();
  });
  Pump();
  for (auto& error : SceneErrors(holder)) errors.push_back(std::move(error));
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_EQ(errors[0].sceneHash, kHash);
  EXPECT_EQ(errors[0].taskId, 0u);
  EXPECT_TRUE(SceneErrors(idle).empty());  // it held none of the job's tasks
}

TEST_F(DispatcherTest, ASceneAnotherJobStillUsesIsNotReportedGone) {
  dispatcher_.AddJob(2, 0, 4, 4, kHash, "{\"scene\": 1}");
  FakeWorker worker(context_, dispatcher_.BoundEndpoint(), 1);
  EnqueueTasks(1, 1);
  ASSERT_EQ(TasksFor(worker, 1).size(), 1u);
  dispatcher_.RemoveJob(1);
  Pump();
  EXPECT_TRUE(SceneErrors(worker).empty());
}

// Assets held in memory, as the farm's store holds them on disk.
class MemoryAssets : public AssetSource {
 public:
  std::string Add(std::string bytes) {
    std::string hash = wire::Sha256Hex(bytes);
    assets_[hash] = std::move(bytes);
    return hash;
  }
  std::optional<uint64_t> SizeOf(const std::string& hash) const override {
    auto found = assets_.find(hash);
    if (found == assets_.end()) return std::nullopt;
    return found->second.size();
  }
  std::string ReadPiece(const std::string& hash, uint64_t offset, size_t maxBytes) const override {
    return assets_.at(hash).substr(offset, maxBytes);
  }

 private:
  std::map<std::string, std::string> assets_;
};

constexpr size_t kMiB = size_t{1} << 20;

// Bytes that differ from piece to piece, so that a piece out of place shows.
std::string Pattern(size_t size) {
  std::string bytes(size, '\0');
  for (size_t i = 0; i < size; ++i) bytes[i] = static_cast<char>((i * 7 + i / 4093) % 251);
  return bytes;
}

class DispatcherAssetTest : public ::testing::Test {
 protected:
  DispatcherAssetTest() : dispatcher_("tcp://127.0.0.1:*", clock_, HeartbeatPolicy{}, &assets_) {}

  std::unique_ptr<FakeWorker> Connect() {
    auto worker = std::make_unique<FakeWorker>(context_, dispatcher_.BoundEndpoint(), 1);
    const size_t known = dispatcher_.registry().workers().size();
    for (int i = 0; i < 1000 && dispatcher_.registry().workers().size() == known; ++i) {
      dispatcher_.Poll(Milliseconds(5), sink_);
    }
    EXPECT_EQ(dispatcher_.registry().workers().size(), known + 1);
    return worker;
  }
  // The worker's request read and one turn of pieces sent: nothing else is on its way in.
  void Ask(FakeWorker& worker, const std::string& hash) {
    worker.Send(wire::AssetGet{hash});
    dispatcher_.Receive(Milliseconds(10000), sink_);
    dispatcher_.Flush();
  }
  // Pumps until the worker has had the asset's last piece; returns every piece it got.
  std::vector<wire::AssetPiece> Collect(FakeWorker& worker, std::vector<wire::AssetPiece> pieces = {}) {
    for (int i = 0; i < 2000 && (pieces.empty() || !pieces.back().IsLast()); ++i) {
      dispatcher_.Poll(Milliseconds(5), sink_);
      for (auto& piece : worker.Pieces()) pieces.push_back(std::move(piece));
    }
    return pieces;
  }
  // Waits (bounded) for what the dispatcher has sent already.
  std::vector<wire::AssetPiece> Arrived(FakeWorker& worker, size_t count) {
    std::vector<wire::AssetPiece> pieces;
    for (int i = 0; i < 2000 && pieces.size() < count; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
      for (auto& piece : worker.Pieces()) pieces.push_back(std::move(piece));
    }
    return pieces;
  }

  MemoryAssets assets_;
  FakeClock clock_;
  zmq::context_t context_;
  Dispatcher dispatcher_;
  RecordingSink sink_;
};

std::string Concatenated(const std::vector<wire::AssetPiece>& pieces) {
  std::string bytes;
  for (const auto& piece : pieces) bytes += piece.bytes;
  return bytes;
}

TEST_F(DispatcherAssetTest, AnAssetArrivesInPiecesInOrderOfOffset) {
  const std::string asset = Pattern(40 * kMiB);
  const std::string hash = assets_.Add(asset);
  auto worker = Connect();
  worker->Send(wire::AssetGet{hash});
  std::vector<wire::AssetPiece> pieces = Collect(*worker);
  ASSERT_EQ(pieces.size(), 3u);
  const std::vector<uint64_t> offsets{0, 16 * kMiB, 32 * kMiB};
  for (size_t i = 0; i < pieces.size(); ++i) {
    EXPECT_EQ(pieces[i].assetHash, hash);
    EXPECT_EQ(pieces[i].offset, offsets[i]);
    EXPECT_EQ(pieces[i].totalSize, asset.size());
    EXPECT_LE(pieces[i].bytes.size(), wire::kMaxAssetPieceBytes);
  }
  EXPECT_TRUE(Concatenated(pieces) == asset);
  EXPECT_EQ(dispatcher_.counters().assetsSent, 1u);
  EXPECT_EQ(dispatcher_.counters().assetBytesSent, asset.size());
}

TEST_F(DispatcherAssetTest, AnEmptyAssetIsOneEmptyPiece) {
  const std::string hash = assets_.Add("");
  auto worker = Connect();
  worker->Send(wire::AssetGet{hash});
  std::vector<wire::AssetPiece> pieces = Collect(*worker);
  ASSERT_EQ(pieces.size(), 1u);
  EXPECT_EQ(pieces[0].assetHash, hash);
  EXPECT_EQ(pieces[0].offset, 0u);
  EXPECT_EQ(pieces[0].totalSize, 0u);
  EXPECT_TRUE(pieces[0].bytes.empty());
  EXPECT_EQ(dispatcher_.counters().assetsSent, 1u);
  EXPECT_EQ(dispatcher_.counters().assetBytesSent, 0u);
}

TEST_F(DispatcherAssetTest, AnUnknownAssetIsAnErrorNamingIt) {
  const std::string unknown = wire::Sha256Hex("never stored");
  auto worker = Connect();
  worker->Send(wire::AssetGet{unknown});
  std::vector<wire::Error> errors;
  for (int i = 0; i < 2000 && errors.empty(); ++i) {
    dispatcher_.Poll(Milliseconds(5), sink_);
    for (auto& m : worker->Drain()) {
      ASSERT_FALSE(std::holds_alternative<wire::AssetPiece>(m));
      if (auto* e = std::get_if<wire::Error>(&m)) errors.push_back(*e);
    }
  }
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_EQ(errors[0].assetHash, unknown);
  EXPECT_EQ(errors[0].taskId, 0u);
  EXPECT_EQ(errors[0].sceneHash, "");
  EXPECT_NE(errors[0].message.find(unknown), std::string::npos) << errors[0].message;
  EXPECT_EQ(dispatcher_.counters().assetsSent, 0u);
  EXPECT_EQ(dispatcher_.counters().assetBytesSent, 0u);
}

TEST_F(DispatcherAssetTest, TwoWorkersFetchingAtOnceBothGetTheWholeAsset) {
  const std::string first = Pattern(40 * kMiB), second = Pattern(20 * kMiB) + "second";
  const std::string firstHash = assets_.Add(first), secondHash = assets_.Add(second);
  auto one = Connect();
  auto two = Connect();
  one->Send(wire::AssetGet{firstHash});
  two->Send(wire::AssetGet{secondHash});
  std::vector<wire::AssetPiece> ones, twos;
  for (int i = 0; i < 2000 && !(!ones.empty() && ones.back().IsLast() && !twos.empty() && twos.back().IsLast());
       ++i) {
    dispatcher_.Poll(Milliseconds(5), sink_);
    for (auto& piece : one->Pieces()) ones.push_back(std::move(piece));
    for (auto& piece : two->Pieces()) twos.push_back(std::move(piece));
  }
  EXPECT_EQ(ones.size(), 3u);
  EXPECT_EQ(twos.size(), 2u);
  EXPECT_TRUE(Concatenated(ones) == first);
  EXPECT_TRUE(Concatenated(twos) == second);
  EXPECT_EQ(dispatcher_.counters().assetsSent, 2u);
  EXPECT_EQ(dispatcher_.counters().assetBytesSent, first.size() + second.size());
}

TEST_F(DispatcherAssetTest, AWorkerThatSaysDisconnectMidDownloadIsSentNoMorePieces) {
  const std::string asset = Pattern(40 * kMiB);
  const std::string hash = assets_.Add(asset);
  auto worker = Connect();
  Ask(*worker, hash);  // one turn: two pieces of three
  std::vector<wire::AssetPiece> pieces = Arrived(*worker, 2);
  ASSERT_EQ(pieces.size(), 2u);
  ASSERT_FALSE(pieces.back().IsLast());
  worker->Send(wire::Disconnect{});
  dispatcher_.Receive(Milliseconds(10000), sink_);  // the goodbye, nothing else
  for (int i = 0; i < 5; ++i) dispatcher_.Poll(Milliseconds(5), sink_);
  EXPECT_TRUE(dispatcher_.registry().workers().empty());
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_TRUE(worker->Pieces().empty());
  EXPECT_EQ(dispatcher_.counters().assetsSent, 0u);
  EXPECT_EQ(dispatcher_.counters().assetBytesSent, 32 * kMiB);
}

// A worker asks again only after it dropped what it had (its disk refused a piece, say):
// the asset starts over, instead of going on where the dropped download was.
TEST_F(DispatcherAssetTest, AnAssetAskedForAgainStartsOver) {
  const std::string asset = Pattern(40 * kMiB);
  const std::string hash = assets_.Add(asset);
  auto worker = Connect();
  Ask(*worker, hash);
  ASSERT_EQ(Arrived(*worker, 2).size(), 2u);
  Ask(*worker, hash);
  std::vector<wire::AssetPiece> pieces = Collect(*worker);
  ASSERT_FALSE(pieces.empty());
  EXPECT_EQ(pieces.front().offset, 0u);
  EXPECT_TRUE(Concatenated(pieces) == asset);
}

// A worker gone without a goodbye (killed) stays in the registry until it has been silent
// long enough; sending to it fails meanwhile, and that must not hold up the others' pieces.
TEST_F(DispatcherAssetTest, AWorkerGoneWithoutAGoodbyeHoldsUpNoOtherDownload) {
  const std::string big = Pattern(100 * kMiB), small = Pattern(20 * kMiB) + "small";
  const std::string bigHash = assets_.Add(big), smallHash = assets_.Add(small);
  auto gone = Connect();
  auto staying = Connect();
  Ask(*gone, bigHash);
  ASSERT_EQ(Arrived(*gone, 2).size(), 2u);
  gone.reset();
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // the router sees the connection close
  staying->Send(wire::AssetGet{smallHash});
  std::vector<wire::AssetPiece> pieces = Collect(*staying);
  EXPECT_TRUE(Concatenated(pieces) == small);
  EXPECT_EQ(dispatcher_.registry().workers().size(), 2u);  // the fake clock never expires it
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
