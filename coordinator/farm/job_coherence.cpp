#include "coordinator/farm/job_coherence.h"

#include <utility>

namespace tcfarm {

JobCoherence::JobCoherence(std::filesystem::path spillFolder, size_t pendingFrameBytes)
    : waiting_(std::move(spillFolder), pendingFrameBytes) {}

std::vector<JobCoherence::ChangeMask> JobCoherence::Add(int frame, const Image& image) {
  std::vector<ChangeMask> masks;
  if (frame != nextFrame_) {
    waiting_.Put(frame, image);
    return masks;
  }
  masks.push_back(TakeInOrder(image));
  while (std::optional<Image> next = waiting_.Take(nextFrame_)) masks.push_back(TakeInOrder(*next));
  return masks;
}

// The first frame has nothing to change from, so its mask is all white.
JobCoherence::ChangeMask JobCoherence::TakeInOrder(const Image& frame) {
  std::vector<uint8_t> unchanged;
  analyzer_.Add(frame, &unchanged);  // may throw: the frame's turn stays
  return ChangeMask{nextFrame_++, std::move(unchanged)};
}

}  // namespace tcfarm
