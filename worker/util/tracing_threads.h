// The tracing threads: a TBB task arena of the requested size. Embree builds its scenes
// with TBB as well, so both share one set of threads instead of two sets competing for the
// cores. Which thread runs a chunk varies from run to run; callers must make each chunk's
// output independent of that (tracing writes each pixel to its own slot).
#pragma once

#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <cstddef>
#include <functional>
#include <memory>
#include <mutex>

namespace tcfarm {

class TracingThreads {
 public:
  // threadCount 0 means one per hardware thread.
  explicit TracingThreads(unsigned threadCount = 0);
  ~TracingThreads();
  TracingThreads(const TracingThreads&) = delete;
  TracingThreads& operator=(const TracingThreads&) = delete;

  unsigned ThreadCount() const { return threadCount_; }

  // Calls body(begin, end) over [0, count) in the chunks [k * chunkSize, (k + 1) * chunkSize)
  // (the last one shorter), on up to ThreadCount() threads, the caller's among them;
  // returns when all chunks are done and rethrows the first exception a chunk threw. A
  // thread runs one chunk at a time, start to end, so a chunk may keep per-thread state and
  // time itself with the thread's CPU clock. One loop at a time: concurrent callers are
  // serialised.
  void ParallelFor(size_t count, size_t chunkSize,
                   const std::function<void(size_t begin, size_t end)>& body);

 private:
  unsigned threadCount_;
  // Set only when more threads are asked for than TBB starts by default (one per core the
  // process may use); raises TBB's process-wide limit while this pool lives.
  std::unique_ptr<tbb::global_control> parallelismLimit_;
  tbb::task_arena arena_;
  std::mutex loopMutex_;
};

}  // namespace tcfarm
