// Who traced which pixels of each frame of a job that promises exactness. When a worker
// is found to return wrong values, the ledger names the frames its values can have
// reached: those it traced and, as far as its horizons could carry copies of them, the
// window that followed each. It also names the worker whose value a frame shows at a pixel
// that the frame's own tasks traced; a copy names nobody (farm/exactness_audit.h).
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

  // Who sent the value `frame` shows at `pixel`, where the frame's own tasks traced it:
  // the one worker whose task there covered it. nullopt where no task of the frame traced
  // it (a copy, or a frame kept from before a restart) or where tasks of two workers did
  // (a task requeued while its first worker still answered): then no single worker is
  // known to have sent the value shown, and nobody can be held to it.
  std::optional<std::string> TracerAt(int frame, uint32_t pixel) const;

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
