// Which workers traced part of each frame of a job, and how far the job may copy what they
// traced. When a worker is found to return wrong values, the ledger names the frames its
// values can have reached: those it traced and, as far as horizons or bins could carry
// copies of them, the window that followed each. Checks of a frame avoid the workers whose
// values it may show. It holds no pixels: evidence against a worker is a value it sent,
// compared by the referee (farm/referee_sample.h), never a lookup of who traced a pixel.
#pragma once

#include <map>
#include <set>
#include <string>

namespace tcfarm {

class TracerLedger {
 public:
  // `worker` traced part of `frame` (the job's numbering); the job may copy its values
  // through frame + window.
  void Record(int frame, const std::string& worker, int window);

  // Every worker that traced some pixel of the frame.
  std::set<std::string> WorkersOf(int frame) const;
  // Every worker whose values the frame may show: traced there, or traced in an earlier
  // frame whose window reaches it.
  std::set<std::string> WorkersReaching(int frame) const;
  // Frames (below frameCount) the worker's values can have reached: each frame it traced
  // part of, and the frames of the window after it, into which copies may go.
  std::set<int> FramesReachedBy(const std::string& worker, int frameCount) const;

 private:
  std::map<int, std::map<std::string, int>> frames_;  // frame -> worker -> the longest window
};

}  // namespace tcfarm
