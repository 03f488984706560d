// The `search` planner: Chapman, Calvert & Dill's RenderSequence / Search (section 3 of
// the paper; docs/architecture.md, section 3.2) as a pure state machine.
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
//
// GuardedPlanner (guarded_planner.h) is this planner with a coarse-raster guard plugged
// in; without one the planner is the paper's search, and with binWidth 2 brute force.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <unordered_map>
#include <vector>

#include "proto/pixel_set/pixel_set.h"
#include "coordinator/planner/planner.h"

namespace tcfarm {

class CoarseGuard;

class SearchPlanner : public Planner {
 public:
  // Throws std::invalid_argument naming the bad option and its expected range.
  explicit SearchPlanner(const PlannerOptions& options);
  ~SearchPlanner() override;

  // Every task has window 0: this planner wants no horizons.
  std::vector<TraceTask> TakeReadyTasks() override;

  // As Planner::OnResult; horizons are ignored (no task asks for them).
  bool OnResult(uint64_t taskId, const float* rgb, size_t floatCount, const int32_t* horizons = nullptr,
                size_t horizonCount = 0) override;

  // Frames whose every pixel is known and that no live bin still reads.
  std::vector<FinishedFrame> TakeFinishedFrames() override;

  bool Done() const override;  // every frame finished and taken

  uint64_t TracedPixels() const override { return tracedPixels_; }
  uint64_t CopiedPixels() const override { return copiedPixels_; }
  // At most maxLiveBins * binWidth: each live bin holds at most its own frames.
  size_t LiveFrames() const override { return frames_.size(); }
  void SetWorkers(int workers) override { options_.workers = workers; }
  size_t InFlightTasks() const { return pendingTasks_.size(); }  // emitted, result not yet in

  // Invariant violations (planner bugs, never bad input) throw std::logic_error.

 protected:
  // With a guard, every frame of a bin has its coarse samples traced before the bin is
  // searched, and tiles whose samples change force their pixels into the search.
  // coarseSamples[f], when not empty, holds frame f's samples already traced (RGB in the
  // guard's sample order): they are taken as that frame's traces instead of asked for.
  SearchPlanner(const PlannerOptions& options, std::unique_ptr<CoarseGuard> guard,
                std::vector<std::vector<float>> coarseSamples = {});

 private:
  enum PixelState : uint8_t { kUnknown = 0, kTraced = 1, kCopied = 2 };

  struct Bin {
    int left = 0;
    int right = 0;
    int preparing = 0;    // end-frame (and coarse-sample) traces not yet back; the search starts at 0
    int waiting = 0;      // continuations of this bin not yet run; the bin is done at 0
  };

  struct Frame {
    std::vector<float> rgb;      // empty until the frame's first value (AllocatePixels)
    std::vector<uint8_t> state;  // PixelState per pixel; empty with rgb
    uint64_t knownCount = 0;
    uint64_t tracedCount = 0;
    int readers = 0;                 // bins and waiting searches that will read this frame
    uint64_t fullTraceRequest = 0;   // the in-flight full trace of an end frame, 0 if none
  };

  // What to run when a trace request is complete: either "one of the bin's end frames
  // (or coarse samples) is traced" or "Search(pixels, left, mid) and Search(pixels, mid, right)".
  struct Continuation {
    size_t bin = 0;
    bool isPreparation = false;
    int left = 0;
    int mid = 0;
    int right = 0;
    int depth = 0;  // of the trace at mid: 1 for the bin's first search (0: preparation)
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
  void PrepareFrame(size_t bin, int frame, const PixelSet& pixels);
  void SearchPreparedBin(size_t bin);
  void FinishBin(size_t bin);
  void Search(size_t bin, const PixelSet& pixels, int left, int right, int depth);
  template <typename Equal>
  void Classify(const PixelSet& pixels, const Frame& left, const Frame& right, Equal equal,
                PixelSetBuilder& same, PixelSetBuilder& changed) const;
  uint64_t RequestTrace(int frame, const PixelSet& pixels, Continuation continuation);
  void AddContinuation(uint64_t request, Continuation continuation);
  void RunContinuation(const Continuation& continuation);
  void WriteTraced(Frame& frame, int frameIndex, const PixelSet& pixels, const float* rgb);
  void CopyPixels(const Frame& source, Frame& destination, int destinationIndex, const PixelSet& pixels);
  void MarkKnown(Frame& frame, int frameIndex, Span span, PixelState how);
  // The frame's state, without its pixels until AllocatePixels.
  Frame& FrameAt(int frame);
  void AllocatePixels(Frame& frame) const;
  void AddReader(int frame);
  void RemoveReader(int frame);
  void ReleaseFinishedFrames();

  PlannerOptions options_;
  uint32_t pixelCount_ = 0;
  std::unique_ptr<CoarseGuard> guard_;
  std::vector<std::vector<float>> coarseSamples_;  // traced before the planner began, per frame  // null for the plain search
  PixelSet searchPixels_;               // what a bin searches: all pixels but the coarse samples
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
