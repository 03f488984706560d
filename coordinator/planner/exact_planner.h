// The `exact` planner: validity horizons, beyond the paper (docs/architecture.md,
// section 3.4).
//
// The sequence is cut into segments of L = binWidth frames: segment k covers frames
// [kL, min((k+1)L, frameCount) - 1]. A segment's first frame is traced in full. Every
// trace of a pixel at frame a asks for its horizon h (the window is segEnd - a): the
// first frame at which the pixel may change. The pixel's value is copied into frames
// a+1 .. min(h, segEnd+1)-1 and, if h <= segEnd, it is traced again at h. Nothing else
// is traced, so the output is bit-identical to brute force as long as the horizons are
// conservative (never later than the pixel's first real change).
//
// A frame's tasks can be issued only once every earlier frame of its segment has all
// its results in, since any of them could name this frame as a horizon: a segment
// advances frame by frame, finishing frames that nobody traces by copy. Segments are
// independent, and up to maxLiveBins of them (started in order) advance in parallel,
// which is what gives many workers work. A live segment holds one working RGB buffer
// and one next-trace frame per pixel; finished frames wait for TakeFinishedFrames.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <utility>
#include <unordered_map>
#include <vector>

#include "proto/pixel_set/pixel_set.h"
#include "coordinator/planner/planner.h"

namespace tcfarm {

class ExactPlanner : public Planner {
 public:
  // Throws std::invalid_argument naming the bad option (binWidth, the segment length,
  // must be >= 1). tolerance is ignored: nothing is compared.
  explicit ExactPlanner(const PlannerOptions& options);

  // Tasks carry window = segEnd - frame (0 at a segment's last frame).
  std::vector<TraceTask> TakeReadyTasks() override;
  bool OnResult(uint64_t taskId, const float* rgb, size_t floatCount, const int32_t* horizons = nullptr,
                size_t horizonCount = 0) override;
  std::vector<FinishedFrame> TakeFinishedFrames() override;
  bool Done() const override;

  uint64_t TracedPixels() const override { return tracedPixels_; }
  uint64_t CopiedPixels() const override { return copiedPixels_; }
  // One working frame per live segment: at most maxLiveBins.
  size_t LiveFrames() const override { return segments_.size(); }
  void SetWorkers(int workers) override { options_.workers = workers; }
  size_t InFlightTasks() const { return pendingTasks_.size(); }  // emitted, result not yet in

  // Invariant violations (planner bugs, never bad input) throw std::logic_error.

 private:
  struct Segment {
    int first = 0;
    int last = 0;
    int frame = 0;            // being assembled; every earlier frame of the segment is finished
    std::vector<float> rgb;   // each pixel's value from its latest trace
    // Per pixel, the frame it must be traced at next; last + 1 means never again. Never
    // below `frame`: a pixel cannot be left without a value. Both are empty until the
    // segment's first result.
    std::vector<int32_t> nextTrace;
    PixelSet tracing;         // the pixels traced at `frame`
    size_t tasksLeft = 0;     // tasks of `frame` whose results are not yet in
  };

  struct PendingTask {
    size_t segment = 0;
    int frame = 0;
    int window = 0;
    PixelSet pixels;
  };

  void StartSegments();
  void StartSegment(size_t segment);
  void CompleteFrame(size_t segment);
  PixelSet PixelsToTraceAt(const Segment& segment) const;
  void IssueTasks(size_t segment, Segment& state);
  void WriteResult(Segment& segment, const PendingTask& task, const float* rgb, const int32_t* horizons);
  void FinishFrame(Segment& segment);

  PlannerOptions options_;
  uint32_t pixelCount_ = 0;
  std::vector<std::pair<int, int>> segmentFrames_;  // [first, last] of each segment to render
  size_t nextSegment_ = 0;  // segments start in frame order: those before this one have started

  std::map<size_t, Segment> segments_;  // live segments by index
  std::vector<FinishedFrame> finished_;  // not yet taken

  std::unordered_map<uint64_t, PendingTask> pendingTasks_;
  std::vector<TraceTask> readyTasks_;
  uint64_t nextTaskId_ = 1;  // ids below this were issued; 0 is never a task

  uint64_t tracedPixels_ = 0;
  uint64_t copiedPixels_ = 0;
};

}  // namespace tcfarm
