// The `search` planner: Chapman, Calvert & Dill's RenderSequence / Search (section 3 of
// the paper, DESIGN.md 1.1) as a pure state machine.
//
// The planner emits trace tasks (a frame and a pixel set) and consumes their results;
// it does no I/O, owns no threads and reads no clock, so the dispatcher can drive it
// from its event loop and tests can drive it with a fake tracer.
//
// Bins of width n tile the sequence with shared end frames: bin k covers frames
// [k(n-1), (k+1)(n-1)], and a remainder shorter than n-1 forms a last, smaller bin that
// ends at the last frame (equation 3's a + b). A bin traces both its end frames fully,
// then Search(all pixels, l, r): pixels equal at l and r are copied into l+1 .. r-1; the
// others are traced at j = (l+r)/2 and searched again on [l, j] and [j, r]. Every
// search whose trace has come back proceeds at once, so independent intervals (and up
// to maxLiveBins bins) keep many tasks in flight for parallel workers.
//
// Known flaw, inherited from the paper (section 4): a pixel equal at both ends of an
// interval but different somewhere inside it is copied, wrongly.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <unordered_map>
#include <vector>

#include "pixel_set/pixel_set.h"

namespace tcfarm {

struct PlannerOptions {
  int width = 0;
  int height = 0;
  int frameCount = 0;  // frames 0 .. frameCount-1, relative to the job
  int binWidth = 0;    // the paper's n >= 2; n == 2 traces every pixel of every frame
  // 0: pixels are equal when their float RGB is bitwise equal; otherwise when no
  // channel differs by more than tolerance.
  float tolerance = 0;
  uint32_t maxTaskPixels = 16384;  // larger requests are split so workers share the load
  int maxLiveBins = 4;             // bins searched at once; bounds the frames held in memory
};

struct TraceTask {
  uint64_t id = 0;
  int frame = 0;
  PixelSet pixels;
};

struct FinishedFrame {
  int frame = 0;
  std::vector<float> rgb;        // width * height * 3, linear RGB, row-major
  std::vector<uint8_t> traced;   // width * height; 1 where the pixel was traced, 0 where copied
  uint64_t tracedCount = 0;
};

class SearchPlanner {
 public:
  // Throws std::invalid_argument naming the bad option and its expected range.
  explicit SearchPlanner(const PlannerOptions& options);

  // Every task that can be traced now. Each task is returned once; re-sending a task
  // whose worker died is the dispatcher's business (tracing is deterministic).
  std::vector<TraceTask> TakeReadyTasks();

  // The result of a task: its RGB values in the task's pixel order (ascending index).
  // Returns true when the result was applied and false when the task had already been
  // completed (a re-delivered result is ignored). Throws std::invalid_argument, and
  // changes nothing, for an id never issued, a float count other than 3 * pixels, or a
  // non-finite value (no NaN ever reaches a frame).
  bool OnResult(uint64_t taskId, const float* rgb, size_t floatCount);

  // Frames whose every pixel is known and that no live bin still reads, in no
  // particular order; the planner forgets them once taken.
  std::vector<FinishedFrame> TakeFinishedFrames();

  bool Done() const;  // every frame finished and taken

  uint64_t TracedPixels() const { return tracedPixels_; }
  uint64_t CopiedPixels() const { return copiedPixels_; }
  // Frames being assembled (finished frames waiting in TakeFinishedFrames excluded).
  // At most maxLiveBins * binWidth: each live bin holds at most its own frames.
  size_t LiveFrames() const { return frames_.size(); }
  size_t InFlightTasks() const { return pendingTasks_.size(); }  // emitted, result not yet in

  // Invariant violations (planner bugs, never bad input) throw std::logic_error.

 private:
  enum PixelState : uint8_t { kUnknown = 0, kTraced = 1, kCopied = 2 };

  struct Bin {
    int left = 0;
    int right = 0;
    int endsPending = 0;  // end-frame traces not yet back; the search starts at 0
    int waiting = 0;      // continuations of this bin not yet run; the bin is done at 0
  };

  struct Frame {
    std::vector<float> rgb;
    std::vector<uint8_t> state;  // PixelState per pixel
    uint64_t knownCount = 0;
    uint64_t tracedCount = 0;
    int readers = 0;                 // bins and waiting searches that will read this frame
    uint64_t fullTraceRequest = 0;   // the in-flight full trace of an end frame, 0 if none
  };

  // What to run when a trace request is complete: either "one of the bin's end frames
  // is traced" or "Search(pixels, left, mid) and Search(pixels, mid, right)".
  struct Continuation {
    size_t bin = 0;
    bool isEndFrame = false;
    int left = 0;
    int mid = 0;
    int right = 0;
    PixelSet pixels;
  };

  struct TraceRequest {
    size_t chunksLeft = 0;
    std::vector<Continuation> continuations;
  };

  struct PendingTask {
    uint64_t request = 0;
    int frame = 0;
    PixelSet pixels;
  };

  void StartBins();
  void StartBin(size_t bin);
  void FinishBin(size_t bin);
  void Search(size_t bin, const PixelSet& pixels, int left, int right);
  template <typename Equal>
  void Classify(const PixelSet& pixels, const Frame& left, const Frame& right, Equal equal,
                PixelSetBuilder& same, PixelSetBuilder& changed) const;
  uint64_t RequestTrace(int frame, const PixelSet& pixels, Continuation continuation);
  void AddContinuation(uint64_t request, Continuation continuation);
  void RunContinuation(const Continuation& continuation);
  void ValidateResult(uint64_t taskId, const PendingTask& task, const float* rgb, size_t floatCount) const;
  void WriteTraced(Frame& frame, int frameIndex, const PixelSet& pixels, const float* rgb);
  void CopyPixels(const Frame& source, Frame& destination, int destinationIndex, const PixelSet& pixels);
  void MarkKnown(Frame& frame, int frameIndex, Span span, PixelState how);
  Frame& FrameAt(int frame);
  void AddReader(int frame);
  void RemoveReader(int frame);
  void ReleaseFinishedFrames();

  PlannerOptions options_;
  uint32_t pixelCount_ = 0;
  std::vector<Bin> bins_;
  size_t nextBin_ = 0;   // bins start in frame order: bins before this one have started
  int liveBins_ = 0;

  std::map<int, Frame> frames_;          // frames being assembled, by frame number
  std::vector<bool> released_;           // per frame: handed to TakeFinishedFrames already
  std::vector<FinishedFrame> finished_;  // released, not yet taken

  std::unordered_map<uint64_t, TraceRequest> requests_;
  std::unordered_map<uint64_t, PendingTask> pendingTasks_;
  std::vector<TraceTask> readyTasks_;
  uint64_t nextRequestId_ = 1;
  uint64_t nextTaskId_ = 1;  // ids below this were issued; 0 is never a task

  uint64_t tracedPixels_ = 0;
  uint64_t copiedPixels_ = 0;
};

}  // namespace tcfarm
