#include "worker/util/tracing_threads.h"

#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

namespace tcfarm {
namespace {

TEST(TracingThreads, ZeroThreadsMeansOnePerHardwareThread) {
  TracingThreads pool(0);
  EXPECT_EQ(pool.ThreadCount(), std::max(1u, std::thread::hardware_concurrency()));
  EXPECT_EQ(TracingThreads(3).ThreadCount(), 3u);
}

TEST(TracingThreads, ChunksAreExactlyChunkSizeAndCoverEveryIndexOnce) {
  TracingThreads pool(3);
  for (size_t count : {size_t{0}, size_t{1}, size_t{127}, size_t{128}, size_t{1000}}) {
    std::mutex mutex;
    std::set<std::pair<size_t, size_t>> chunks;
    std::vector<std::atomic<int>> seen(count);
    pool.ParallelFor(count, 128, [&](size_t begin, size_t end) {
      for (size_t i = begin; i < end; ++i) ++seen[i];
      std::lock_guard<std::mutex> lock(mutex);
      chunks.insert({begin, end});
    });
    std::set<std::pair<size_t, size_t>> expected;
    for (size_t begin = 0; begin < count; begin += 128) {
      expected.insert({begin, std::min(count, begin + 128)});
    }
    EXPECT_EQ(chunks, expected) << count << " items";
    for (size_t i = 0; i < count; ++i) ASSERT_EQ(seen[i].load(), 1) << "index " << i;
  }
}

// Each chunk waits until as many chunks as the pool has threads are running at once, so
// the loop finishes early only when the pool really runs that many threads; more than the
// machine's cores included (TBB starts one per core unless told otherwise).
TEST(TracingThreads, RunsTheRequestedNumberOfThreadsAtOnce) {
  for (unsigned threads : {1u, 2u, std::thread::hardware_concurrency() + 2}) {
    TracingThreads pool(threads);
    std::atomic<unsigned> running{0};
    std::atomic<unsigned> peak{0};
    std::mutex mutex;
    std::set<std::thread::id> ids;
    pool.ParallelFor(threads, 1, [&](size_t, size_t) {
      unsigned now = ++running;
      for (unsigned seen = peak; now > seen && !peak.compare_exchange_weak(seen, now);) {
      }
      const auto giveUp = std::chrono::steady_clock::now() + std::chrono::seconds(20);
      while (peak < threads && std::chrono::steady_clock::now() < giveUp) {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
      {
        std::lock_guard<std::mutex> lock(mutex);
        ids.insert(std::this_thread::get_id());
      }
      --running;
    });
    EXPECT_EQ(peak.load(), threads) << threads << " threads asked for";
    EXPECT_EQ(ids.size(), threads) << threads << " threads asked for";
  }
}

TEST(TracingThreads, NeverMoreThreadsThanAskedFor) {
  TracingThreads pool(2);
  std::mutex mutex;
  std::set<std::thread::id> ids;
  pool.ParallelFor(64, 1, [&](size_t, size_t) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    std::lock_guard<std::mutex> lock(mutex);
    ids.insert(std::this_thread::get_id());
  });
  EXPECT_LE(ids.size(), 2u);
}

// Embree builds geometry with TBB loops from inside a chunk. A thread waiting for such a
// loop must not start another chunk meanwhile: the tracer keeps per-thread buffers and
// times each chunk with the thread's CPU clock.
TEST(TracingThreads, AThreadFinishesItsChunkBeforeStartingAnother) {
  TracingThreads pool(4);
  thread_local bool inChunk = false;
  std::atomic<int> overlaps{0};
  std::atomic<long> nestedSum{0};
  pool.ParallelFor(200, 1, [&](size_t, size_t) {
    if (inChunk) ++overlaps;
    inChunk = true;
    // Uneven tasks: other threads take some, so this one runs out of its own while theirs
    // still run, and goes looking for work (without isolation it finds a chunk now and then).
    tbb::parallel_for(0, 16, [&](int i) {
      std::this_thread::sleep_for(std::chrono::microseconds(200 * (i % 7)));
      nestedSum += i;
    });
    inChunk = false;
  });
  EXPECT_EQ(overlaps.load(), 0);
  EXPECT_EQ(nestedSum.load(), 200L * (15 * 16 / 2));
}

TEST(TracingThreads, AChunksExceptionReachesTheCaller) {
  TracingThreads pool(2);
  EXPECT_THROW(pool.ParallelFor(100, 10,
                                [](size_t begin, size_t) {
                                  if (begin == 50) throw std::runtime_error("chunk 5");
                                }),
               std::runtime_error);
  // The pool stays usable.
  std::atomic<size_t> covered{0};
  pool.ParallelFor(100, 10, [&](size_t begin, size_t end) { covered += end - begin; });
  EXPECT_EQ(covered.load(), 100u);
}

}  // namespace
}  // namespace tcfarm
