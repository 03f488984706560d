// A fixed pool of threads for data-parallel loops. Work is handed out in chunks from an
// atomic counter, so which thread runs a chunk varies from run to run; callers must make
// each chunk's output independent of that (tracing writes each pixel to its own slot).
#pragma once

#include <condition_variable>
#include <cstddef>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace tcfarm {

class ThreadPool {
 public:
  // threadCount 0 means one per hardware thread.
  explicit ThreadPool(unsigned threadCount = 0);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  unsigned ThreadCount() const { return static_cast<unsigned>(workers_.size()) + 1; }

  // Calls body(begin, end) over [0, count) in chunks of at most chunkSize, on every
  // thread of the pool plus the caller; returns when all chunks are done. One loop at a
  // time: concurrent callers are serialised.
  void ParallelFor(size_t count, size_t chunkSize,
                   const std::function<void(size_t begin, size_t end)>& body);

 private:
  struct Loop;
  void WorkerMain();
  static void RunChunks(Loop& loop);

  std::vector<std::thread> workers_;
  std::mutex loopMutex_;  // serialises ParallelFor callers
  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable finished_;
  Loop* loop_ = nullptr;
  size_t generation_ = 0;
  unsigned busyWorkers_ = 0;
  bool stopping_ = false;
};

}  // namespace tcfarm
