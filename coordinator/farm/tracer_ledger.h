// Who traced which pixels of each frame of a job that promises exactness. When a worker
// is found to return wrong values, the ledger names the frames its values can have
// reached: those it traced and, as far as its horizons could carry copies of them, the
// window that followed each. A copied pixel's value is traced-then-copied, so the ledger
// also finds which worker traced the value a frame shows at a pixel.
#pragma once

#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "proto/pixel_set/pixel_set.h"

namespace tcfarm {

class TracerLedger {
 public:
  // `worker` traced `pixels` of `frame` (the job's numbering) in a task with `window`.
  // Empty pixels record only who traced the frame (what a job that does not trace wrong
  // values back needs).
  void Record(int frame, const std::string& worker, const PixelSet& pixels, int window);

  // Every worker that traced some pixel of the frame.
  std::set<std::string> WorkersOf(int frame) const;
  // Every worker whose values the frame may show: traced there, or traced in an earlier
  // frame whose window reaches it.
  std::set<std::string> WorkersReaching(int frame) const;

  struct Source {
    int frame = 0;
    std::string worker;
  };
  // Where the value `frame` shows at `pixel` was traced: the latest frame at or before
  // `frame` whose tasks traced it. nullopt when no recorded task did (a frame kept from
  // before a restart, or a bug that copied a pixel never traced).
  std::optional<Source> SourceOf(int frame, uint32_t pixel) const;

  // Frames (below frameCount) the worker's values can have reached: each frame it traced
  // part of, and the frames of the window after it, into which horizons may copy.
  std::set<int> FramesReachedBy(const std::string& worker, int frameCount) const;

  // No dispute will be raised below `frame` any more: the pixels traced in frames whose
  // copies cannot reach it are forgotten (who traced them and their windows are kept,
  // for FramesReachedBy). Bounds the ledger by the frames in flight, not the job.
  void ForgetPixelsBefore(int frame);
  uint64_t PixelSetsHeld() const { return pixelSetsHeld_; }

 private:
  struct Traced {
    std::vector<PixelSet> tasks;  // not merged: a lookup is rare, a record is not
    int window = 0;               // the longest of its tasks'
  };
  std::map<int, std::map<std::string, Traced>> frames_;
  int pixelsForgottenBelow_ = 0;  // frames below it hold no pixel sets
  uint64_t pixelSetsHeld_ = 0;
};

}  // namespace tcfarm
