#include "worker/util/tracing_threads.h"

#include <tbb/blocked_range.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <thread>

namespace tcfarm {
namespace {

unsigned ResolveThreadCount(unsigned threadCount) {
  return threadCount != 0 ? threadCount : std::max(1u, std::thread::hardware_concurrency());
}

}  // namespace

TracingThreads::TracingThreads(unsigned threadCount)
    : threadCount_(ResolveThreadCount(threadCount)),
      parallelismLimit_(threadCount_ > static_cast<unsigned>(tbb::info::default_concurrency())
                            ? std::make_unique<tbb::global_control>(
                                  tbb::global_control::max_allowed_parallelism, threadCount_)
                            : nullptr),
      arena_(static_cast<int>(threadCount_)) {}

TracingThreads::~TracingThreads() = default;

void TracingThreads::ParallelFor(size_t count, size_t chunkSize,
                             const std::function<void(size_t, size_t)>& body) {
  if (count == 0) return;
  chunkSize = std::max<size_t>(1, chunkSize);
  const size_t chunkCount = (count + chunkSize - 1) / chunkSize;
  std::lock_guard<std::mutex> callerLock(loopMutex_);
  arena_.execute([&] {
    // One task per chunk index, never split further: the chunks are exactly those of
    // chunkSize, whatever the thread count.
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, chunkCount, 1),
        [&](const tbb::blocked_range<size_t>& chunks) {
          for (size_t k = chunks.begin(); k != chunks.end(); ++k) {
            // A chunk may run TBB loops of its own (Embree builds a frame's geometry on
            // first use). Waiting in one, a thread could otherwise pick up another of our
            // chunks midway through this one: that would overwrite this chunk's per-thread
            // buffers, count CPU time twice, or block on a lock this chunk holds.
            tbb::this_task_arena::isolate(
                [&] { body(k * chunkSize, std::min(count, (k + 1) * chunkSize)); });
          }
        },
        tbb::simple_partitioner());
  });
}

}  // namespace tcfarm
