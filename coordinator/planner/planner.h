// The planner interface: what the farm drives for every job, whatever the strategy
// (docs/architecture.md, section 3).
//
// A planner is a pure state machine. It emits trace tasks (a frame and a pixel set) and
// consumes their results; it does no I/O, owns no threads and reads no clock, so the
// dispatcher can drive it from its event loop and tests can drive it with a fake tracer.
// Frames are relative to the job (0 .. frameCount-1) throughout.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "proto/frame/frame_buffer_pool.h"
#include "proto/pixel_set/pixel_set.h"
#include "coordinator/planner/strategy.h"

namespace tcfarm {

struct PlannerOptions {
  int width = 0;
  int height = 0;
  int frameCount = 0;  // frames 0 .. frameCount-1, relative to the job
  // search and guarded: the paper's bin width n >= 2; n == 2 traces every pixel of every frame.
  // exact: the segment length L >= 1. Segment k covers frames [kL, min((k+1)L, frameCount) - 1]
  // and starts with a full trace, so L == 1 traces every pixel of every frame.
  int binWidth = 0;
  // search and guarded: 0 means pixels are equal when their float RGB is bitwise equal;
  // otherwise when no channel differs by more than tolerance. exact ignores it: its
  // output is bit-identical to brute force.
  float tolerance = 0;
  uint32_t maxTaskPixels = 16384;  // larger requests are split so workers share the load
  // Workers a trace request is spread over: it is cut into this many tasks, none smaller
  // than kMinTaskPixels (a task's fixed costs) nor larger than maxTaskPixels. Parallelism
  // then comes from within a frame, not only from more bins or segments.
  int workers = 1;
  // Each task pays fixed costs on its worker (its horizon oracle's proxies, the frame's
  // top-level scene): at 1024 pixels they showed as 15 % more CPU for a 64-worker farm
  // than for one worker, at 4096 they are lost in the noise.
  static constexpr uint32_t kMinTaskPixels = 4096;
  int maxLiveBins = 4;             // bins (segments) worked on at once; bounds the frames held in memory
  // guarded: the coarse raster has one sample per coarseTile x coarseTile tile (the paper's 8).
  int coarseTile = 8;
  // A resumed job's frames already in the store (index = frame; empty: none). Every frame
  // of a bin is derived from that bin's own traces, so a bin (search, guarded) whose frames
  // are all kept is not planned at all, and the others run exactly as they would have:
  // their kept frames are traced again and still come out of TakeFinishedFrames, for the
  // caller to drop. An exact segment starts at its first frame not kept (a full trace
  // there), since exact's output does not depend on where segments start.
  std::vector<bool> keptFrames;
  // exact: where a finished frame's pixel buffer is taken from (buffers of frames already
  // written, FrameWriterOptions::recycle); none: each is allocated anew.
  std::shared_ptr<FrameBufferPool> frameBuffers = nullptr;
};

// Planner task ids fit in this many bits (a planner may use the top one of them, as
// auto's survey does); the bits above are the farm's own (JobRun).
constexpr int kPlannerTaskIdBits = 62;

struct TraceTask {
  uint64_t id = 0;
  int frame = 0;
  PixelSet pixels;
  // window > 0: the worker must also return, per pixel, its validity horizon: the first
  // frame h in [frame+1, frame+window+1] at which the pixel may change (frame+window+1
  // means "valid through the whole window"). 0: no horizons wanted.
  int window = 0;
  // Dependencies, for the job's span: a task depends on the tasks of earlier steps of its
  // chain (an exact segment's earlier frames, a search bin's shallower levels); chains are
  // independent, except that every chain waits for the prelude (auto's survey).
  int chain = 0;
  int step = 0;
  static constexpr int kPreludeChain = -1;
};

struct FinishedFrame {
  int frame = 0;
  std::vector<float> rgb;        // width * height * 3, linear RGB, row-major
  std::vector<uint8_t> traced;   // width * height; 1 where the pixel was traced at this frame, 0 where copied
  uint64_t tracedCount = 0;
};

class Planner {
 public:
  virtual ~Planner() = default;

  // Every task that can be traced now. Each task is returned once; re-sending a task
  // whose worker died is the dispatcher's business (tracing is deterministic).
  virtual std::vector<TraceTask> TakeReadyTasks() = 0;

  // The result of a task: its RGB values in the task's pixel order (ascending index) and,
  // for a task with window > 0, one horizon per pixel in the same order (for a task with
  // window 0 horizons are not needed and are ignored). Returns true when the result was
  // applied and false when the task had already been completed (a re-delivered result is
  // ignored). Throws std::invalid_argument, and changes nothing, for an id never issued, a
  // float count other than 3 * pixels, a non-finite value (no NaN ever reaches a frame),
  // or horizons missing, of the wrong count, or outside [frame+1, frame+window+1].
  virtual bool OnResult(uint64_t taskId, const float* rgb, size_t floatCount, const int32_t* horizons = nullptr,
                        size_t horizonCount = 0) = 0;

  // Frames whose every pixel is known and that the planner no longer reads, in no
  // particular order; the planner forgets them once taken.
  virtual std::vector<FinishedFrame> TakeFinishedFrames() = 0;

  virtual bool Done() const = 0;  // every frame finished and taken

  // Live workers now: trace requests issued from here on are spread over them.
  virtual void SetWorkers(int workers) = 0;

  virtual uint64_t TracedPixels() const = 0;
  virtual uint64_t CopiedPixels() const = 0;
  // Frames being assembled (finished frames waiting in TakeFinishedFrames excluded): the
  // planner's memory, bounded through maxLiveBins.
  virtual size_t LiveFrames() const = 0;
};

namespace planner_internal {
// Whether frames [first, last] are all in options.keptFrames.
bool AllKept(const PlannerOptions& options, int first, int last);
}  // namespace planner_internal

// Empties a planner's queue of ready tasks or finished frames into the caller's hands.
template <typename T>
std::vector<T> TakeAll(std::vector<T>& queue) {
  std::vector<T> taken;
  taken.swap(queue);
  return taken;
}

// brute is search with binWidth 2 (options.binWidth is ignored for it). Throws
// std::invalid_argument naming the bad option and its expected range, or for kAuto
// (resolve it first: ResolveStrategy).
std::unique_ptr<Planner> MakePlanner(Strategy strategy, const PlannerOptions& options);

// Shared by the planners' implementations; not for callers.
namespace planner_internal {

// A trace request cut into tasks as options.workers and the task size bounds say.
std::vector<PixelSet> SplitForWorkers(const PixelSet& pixels, const PlannerOptions& options);

// Invariants of a planner itself (planner bugs, never bad input). They throw
// std::logic_error rather than abort so that a daemon can fail the one job and go on
// serving the others. `planner` names the planner in the message ("search planner").
void Check(bool condition, const char* planner, const std::string& what);
[[noreturn]] void FailCheck(const char* planner, const std::string& what);

// Prints both values: "<what> is <actual>, expected <expected>". For integers.
template <typename A, typename B>
void CheckEqual(const A& actual, const B& expected, const char* planner, const char* what) {
  if (actual == expected) return;
  FailCheck(planner, std::string(what) + " is " + std::to_string(actual) + ", expected " + std::to_string(expected));
}

// Throws std::invalid_argument "PlannerOptions.<name> is <value>; expected <expected>".
void RequireOption(bool valid, const char* name, long long value, const char* expected);

// The bins of search and guarded: they share end frames, so bin k starts where bin k-1
// ends; the last bin may be shorter. A single frame is a bin of its own whose two ends
// coincide. Each is [left, right].
std::vector<std::pair<int, int>> TileBins(int frameCount, int binWidth);

// Everything but binWidth and coarseTile, whose ranges depend on the strategy.
void ValidateCommonOptions(const PlannerOptions& options);

// Throws std::invalid_argument unless rgb holds 3 finite floats per pixel.
void ValidateRgb(uint64_t taskId, int frame, uint64_t pixels, const float* rgb, size_t floatCount);

// Throws std::invalid_argument unless there is one horizon per pixel, each in
// [frame+1, frame+window+1]. Only for window > 0.
void ValidateHorizons(uint64_t taskId, int frame, int window, uint64_t pixels, const int32_t* horizons,
                      size_t horizonCount);

}  // namespace planner_internal
}  // namespace tcfarm
