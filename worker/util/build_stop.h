// A request, from another thread, to give up a scene build under way: the worker sets it
// when it is told to stop (SIGTERM), so that a build of a huge scene does not hold the
// process for as long as the build takes. A build looks at it between its steps and in
// its long loops (Embree's own tree builds through their progress monitor) and throws
// BuildStopped; nothing it built is kept.
#pragma once

#include <atomic>
#include <stdexcept>

namespace tcfarm {

class BuildStopped : public std::runtime_error {
 public:
  BuildStopped() : std::runtime_error("scene build stopped: the worker is stopping") {}
};

// Null: the build cannot be stopped (the reference renderer, tests).
using BuildStop = const std::atomic<bool>*;

inline bool StopRequested(BuildStop stop) { return stop && stop->load(std::memory_order_relaxed); }

inline void ThrowIfStopRequested(BuildStop stop) {
  if (StopRequested(stop)) throw BuildStopped();
}

}  // namespace tcfarm
