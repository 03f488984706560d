#include "util/thread_pool.h"

#include <atomic>

namespace tcfarm {

struct ThreadPool::Loop {
  size_t count;
  size_t chunkSize;
  const std::function<void(size_t, size_t)>* body;
  std::atomic<size_t> next{0};
};

ThreadPool::ThreadPool(unsigned threadCount) {
  if (threadCount == 0) threadCount = std::max(1u, std::thread::hardware_concurrency());
  // The caller of ParallelFor works too, so the pool owns one thread fewer.
  for (unsigned i = 1; i < threadCount; ++i) workers_.emplace_back([this] { WorkerMain(); });
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  for (auto& worker : workers_) worker.join();
}

void ThreadPool::RunChunks(Loop& loop) {
  for (;;) {
    size_t begin = loop.next.fetch_add(loop.chunkSize);
    if (begin >= loop.count) return;
    (*loop.body)(begin, std::min(loop.count, begin + loop.chunkSize));
  }
}

void ThreadPool::WorkerMain() {
  size_t seenGeneration = 0;
  for (;;) {
    Loop* loop;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] { return stopping_ || generation_ != seenGeneration; });
      if (stopping_) return;
      seenGeneration = generation_;
      loop = loop_;
      // A worker that wakes after the loop already finished finds nothing to join.
      if (loop == nullptr) continue;
      ++busyWorkers_;
    }
    RunChunks(*loop);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      --busyWorkers_;
    }
    finished_.notify_all();
  }
}

void ThreadPool::ParallelFor(size_t count, size_t chunkSize,
                             const std::function<void(size_t, size_t)>& body) {
  if (count == 0) return;
  chunkSize = std::max<size_t>(1, chunkSize);
  std::lock_guard<std::mutex> callerLock(loopMutex_);
  Loop loop{count, chunkSize, &body};
  if (workers_.empty() || count <= chunkSize) {
    RunChunks(loop);
    return;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    loop_ = &loop;
    ++generation_;
  }
  wake_.notify_all();
  RunChunks(loop);
  // Workers that woke for this loop must leave it before `loop` goes out of scope.
  std::unique_lock<std::mutex> lock(mutex_);
  finished_.wait(lock, [&] { return busyWorkers_ == 0; });
  loop_ = nullptr;
}

}  // namespace tcfarm
