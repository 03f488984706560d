// The dispatcher's task queue alone: stride order by priority, what a worker may take,
// requeues to the front, and the tasks no connected worker may take.
#include "coordinator/dispatch/task_queue.h"

#include <gtest/gtest.h>

namespace tcfarm {
namespace {

WorkerState Worker(const std::string& identity, const std::string& principal) {
  WorkerState worker;
  worker.identity = identity;
  worker.principal = principal;
  return worker;
}

DispatchTask Task(uint64_t jobId, int frame) {
  DispatchTask task;
  task.jobId = jobId;
  task.frame = frame;
  return task;
}

TEST(TaskQueueTest, JobsShareByPriorityWeight) {
  TaskQueue queue;
  queue.AddJob(1, 0, 8, 8, "scene");   // weight 1
  queue.AddJob(2, 2, 8, 8, "scene");   // weight 3
  for (int frame = 0; frame < 8; ++frame) {
    queue.Enqueue(Task(1, frame));
    queue.Enqueue(Task(2, frame));
  }
  const WorkerState worker = Worker("w", "p");
  std::map<uint64_t, int> taken;
  for (int i = 0; i < 8; ++i) {
    const uint64_t id = queue.TakeFor(worker);
    ASSERT_NE(id, 0u);
    ++taken[queue.Sent(id, "w", SteadyTime{}).task.jobId];
  }
  EXPECT_EQ(taken[1], 2);
  EXPECT_EQ(taken[2], 6);
  EXPECT_EQ(queue.Pending(), 8u);
  EXPECT_EQ(queue.InFlight(), 8u);
}

TEST(TaskQueueTest, AWorkerNeverTakesATaskItFailedOrThatAvoidsIt) {
  TaskQueue queue;
  queue.AddJob(1, 0, 8, 8, "scene");
  DispatchTask avoiding = Task(1, 0);
  avoiding.avoid.insert("checked");
  queue.Enqueue(avoiding);
  EXPECT_EQ(queue.TakeFor(Worker("a", "checked")), 0u);
  const uint64_t id = queue.TakeFor(Worker("b", "other"));
  ASSERT_NE(id, 0u);
  queue.Sent(id, "b", SteadyTime{}).failedBy.insert("b");
  EXPECT_EQ(queue.Requeue({id}), (std::map<uint64_t, size_t>{{1, 1}}));
  EXPECT_EQ(queue.TakeFor(Worker("b", "other")), 0u);
  EXPECT_EQ(queue.TakeFor(Worker("c", "third")), id);
}

TEST(TaskQueueTest, ARequeuedTaskGoesFirstAndPendingOnesAreNotRequeued) {
  TaskQueue queue;
  queue.AddJob(1, 0, 8, 8, "scene");
  queue.Enqueue(Task(1, 0));
  queue.Enqueue(Task(1, 1));
  const WorkerState worker = Worker("w", "p");
  const uint64_t first = queue.TakeFor(worker);
  queue.Sent(first, "w", SteadyTime{});
  EXPECT_EQ(queue.Find(first)->holder, "w");
  const uint64_t second = queue.TakeFor(worker);
  queue.Sent(second, "w", SteadyTime{});
  EXPECT_EQ(queue.Requeue({second}).at(1), 1u);
  EXPECT_TRUE(queue.Requeue({second, 999}).empty());  // pending already, and unknown
  EXPECT_TRUE(queue.Find(second)->holder.empty());
  EXPECT_EQ(queue.TakeFor(worker), second);
}

TEST(TaskQueueTest, RemovingAJobDropsItsTasksAndFreesItsScene) {
  TaskQueue queue;
  queue.AddJob(1, 0, 8, 8, "a");
  queue.AddJob(2, 0, 8, 8, "b");
  queue.Enqueue(Task(1, 0));
  queue.Enqueue(Task(1, 1));
  queue.Enqueue(Task(2, 0));
  queue.Sent(queue.TakeFor(Worker("w", "p")), "w", SteadyTime{});
  EXPECT_EQ(queue.RemoveJob(1).size(), 2u);
  EXPECT_FALSE(queue.SceneUsed("a"));
  EXPECT_TRUE(queue.SceneUsed("b"));
  EXPECT_EQ(queue.Pending() + queue.InFlight(), 1u);
  EXPECT_TRUE(queue.RemoveJob(1).empty());
}

TEST(TaskQueueTest, TakesStrandedOnlyTheRefereesTasksNobodyMayTake) {
  TaskQueue queue;
  queue.AddJob(1, 0, 8, 8, "scene");
  DispatchTask check = Task(1, 0);
  check.refereeMayTrace = true;
  queue.Enqueue(check);
  queue.Enqueue(Task(1, 1));  // a planner task waits whoever connects
  EXPECT_TRUE(queue.TakeStranded([](const TaskQueue::Entry&) { return true; }).empty());
  const std::vector<DispatchTask> stranded = queue.TakeStranded([](const TaskQueue::Entry&) { return false; });
  ASSERT_EQ(stranded.size(), 1u);
  EXPECT_EQ(stranded[0].frame, 0);
  EXPECT_EQ(queue.Pending(), 1u);
}

TEST(TaskQueueTest, WeightsAreSymmetricAroundZero) {
  EXPECT_DOUBLE_EQ(TaskQueue::WeightOf(0), 1.0);
  EXPECT_DOUBLE_EQ(TaskQueue::WeightOf(50), 51.0);
  EXPECT_DOUBLE_EQ(TaskQueue::WeightOf(-50), 1.0 / 51.0);
}

}  // namespace
}  // namespace tcfarm
