#include "coordinator/dispatch/task_queue.h"

#include <algorithm>

namespace tcfarm {

// Symmetric around 0 on a log scale: 100 against 0 is what 0 is against -100. A weight
// of 1 + max(0, p) once made every negative priority run like 0.
double TaskQueue::WeightOf(int priority) {
  return priority >= 0 ? 1.0 + priority : 1.0 / (1.0 - priority);
}

bool TaskQueue::MayTake(const Entry& entry, const WorkerState& worker) {
  return !entry.failedBy.count(worker.identity) && !entry.task.avoid.count(worker.principal);
}

void TaskQueue::AddJob(uint64_t jobId, int priority, uint32_t width, uint32_t height,
                       const std::string& sceneHash) {
  Job job;
  job.weight = WeightOf(priority);
  job.width = width;
  job.height = height;
  job.sceneHash = sceneHash;
  // A new job starts level with the others instead of owing them its whole history.
  for (const auto& [id, other] : jobs_) job.pass = std::max(job.pass, other.pass);
  jobs_[jobId] = std::move(job);
}

void TaskQueue::SetPriority(uint64_t jobId, int priority) {
  auto job = jobs_.find(jobId);
  if (job == jobs_.end()) return;
  job->second.weight = WeightOf(priority);
}

std::vector<uint64_t> TaskQueue::RemoveJob(uint64_t jobId) {
  std::vector<uint64_t> removed;
  if (jobs_.erase(jobId) == 0) return removed;
  for (auto it = tasks_.begin(); it != tasks_.end();) {
    if (it->second.task.jobId != jobId) {
      ++it;
      continue;
    }
    if (it->second.pending) --pendingCount_;
    removed.push_back(it->first);
    it = tasks_.erase(it);
  }
  return removed;
}

bool TaskQueue::SceneUsed(const std::string& sceneHash) const {
  return std::any_of(jobs_.begin(), jobs_.end(), [&](const auto& job) { return job.second.sceneHash == sceneHash; });
}

void TaskQueue::Enqueue(DispatchTask task) {
  auto job = jobs_.find(task.jobId);
  if (job == jobs_.end()) return;
  const uint64_t id = nextTaskId_++;
  job->second.pending.push_back(id);
  Entry entry;
  entry.task = std::move(task);
  tasks_.emplace(id, std::move(entry));
  ++pendingCount_;
}

uint64_t TaskQueue::TakeFor(const WorkerState& worker) {
  std::vector<Job*> order;
  for (auto& [id, job] : jobs_) {
    if (!job.pending.empty()) order.push_back(&job);
  }
  // Stride scheduling: the job with the lowest pass goes first.
  std::stable_sort(order.begin(), order.end(), [](const Job* a, const Job* b) { return a->pass < b->pass; });
  for (Job* job : order) {
    for (auto it = job->pending.begin(); it != job->pending.end(); ++it) {
      if (!MayTake(tasks_.at(*it), worker)) continue;
      const uint64_t id = *it;
      job->pending.erase(it);
      job->pass += 1.0 / job->weight;
      return id;
    }
  }
  return 0;
}

TaskQueue::Entry& TaskQueue::Sent(uint64_t taskId, const std::string& holder, SteadyTime now) {
  Entry& entry = tasks_.at(taskId);
  entry.pending = false;
  entry.holder = holder;
  entry.sentAt = now;
  --pendingCount_;
  return entry;
}

std::map<uint64_t, size_t> TaskQueue::Requeue(const std::vector<uint64_t>& taskIds) {
  std::map<uint64_t, size_t> requeued;
  for (uint64_t id : taskIds) {
    auto entry = tasks_.find(id);
    if (entry == tasks_.end() || entry->second.pending) continue;
    auto job = jobs_.find(entry->second.task.jobId);
    if (job == jobs_.end()) continue;
    entry->second.pending = true;
    entry->second.holder.clear();
    ++pendingCount_;
    job->second.pending.push_front(id);
    ++requeued[job->first];
  }
  return requeued;
}

std::vector<DispatchTask> TaskQueue::TakeStranded(const std::function<bool(const Entry&)>& anyoneMayTake) {
  std::vector<DispatchTask> stranded;
  if (pendingCount_ == 0) return stranded;  // the common case on a busy farm's every turn
  for (auto& [jobId, job] : jobs_) {
    for (auto it = job.pending.begin(); it != job.pending.end();) {
      auto entry = tasks_.find(*it);
      if (!entry->second.task.refereeMayTrace || anyoneMayTake(entry->second)) {
        ++it;
        continue;
      }
      stranded.push_back(std::move(entry->second.task));
      tasks_.erase(entry);
      --pendingCount_;
      it = job.pending.erase(it);
    }
  }
  return stranded;
}

TaskQueue::Entry* TaskQueue::Find(uint64_t taskId) {
  auto entry = tasks_.find(taskId);
  return entry == tasks_.end() ? nullptr : &entry->second;
}

}  // namespace tcfarm
