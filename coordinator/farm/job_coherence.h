// A job's coherence (docs/architecture.md, section 3.1): its frames taken in order into
// the sequence analysis, and each one's change mask against the frame before (the
// paper's Figure 5).
//
// Planners release frames out of order (the paper's search finishes bins side by side);
// those that come ahead of their turn wait in PendingFrames, in memory up to a budget and
// on disk beyond it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "coordinator/farm/pending_frames.h"
#include "proto/frame/sequence_analysis.h"

namespace tcfarm {

class JobCoherence {
 public:
  // spillFolder is where frames ahead of their turn wait once pendingFrameBytes of them
  // are held in memory.
  JobCoherence(std::filesystem::path spillFolder, size_t pendingFrameBytes);

  // `frame` relative to the job; white (1) where the pixel is bitwise the previous frame's.
  struct ChangeMask {
    int frame;
    std::vector<uint8_t> unchanged;
  };
  // Takes a finished frame. Returns the change masks of the frames now analysed in order,
  // oldest first: none while `frame` is ahead of its turn, several when it was the one
  // the waiting frames needed. Throws FrameIoError when a waiting frame cannot be spilled
  // or read back.
  // traced, when given (one byte per pixel), promises that every pixel where it is 0 is
  // bitwise the previous frame's (as every planner copies): only the traced pixels are
  // then compared, and only they wait with a frame ahead of its turn. Without it the
  // whole frame is compared, and copied to wait.
  std::vector<ChangeMask> Add(int frame, const Image& image, const std::vector<uint8_t>* traced = nullptr);
  const SequenceAnalyzer& analysis() const { return analyzer_; }
  // The frame whose turn it is: every frame before it is analysed.
  int NextFrame() const { return nextFrame_; }
  // Frames that ever waited on disk rather than in memory.
  uint64_t FramesWaitedOnDisk() const { return waiting_.TotalSpilled(); }

 private:
  ChangeMask TakeInOrder(const Image& frame, const std::vector<uint8_t>* traced = nullptr);
  ChangeMask TakeInOrder(const FrameChanges& frame);

  SequenceAnalyzer analyzer_;
  int nextFrame_ = 0;
  PendingFrames waiting_;
};

}  // namespace tcfarm
