#include "coordinator/farm/job_coherence.h"

#include <utility>
#include <variant>

namespace tcfarm {

JobCoherence::JobCoherence(std::filesystem::path spillFolder, size_t pendingFrameBytes)
    : waiting_(std::move(spillFolder), pendingFrameBytes) {}

std::vector<JobCoherence::ChangeMask> JobCoherence::Add(int frame, const Image& image,
                                                        const std::vector<uint8_t>* traced) {
  std::vector<ChangeMask> masks;
  if (frame != nextFrame_) {
    // Ahead of its turn, so never the first frame (which is taken whole): its traced
    // pixels are all it can have changed.
    waiting_.Put(frame, traced ? PendingFrames::Frame(FrameChanges::Gather(image, *traced))
                               : PendingFrames::Frame(image));
    return masks;
  }
  masks.push_back(TakeInOrder(image, traced));
  while (std::optional<PendingFrames::Frame> next = waiting_.Take(nextFrame_)) {
    masks.push_back(std::visit([this](const auto& waiting) { return TakeInOrder(waiting); }, *next));
  }
  return masks;
}

// The first frame has nothing to change from, so its mask is all white.
JobCoherence::ChangeMask JobCoherence::TakeInOrder(const Image& frame, const std::vector<uint8_t>* traced) {
  std::vector<uint8_t> unchanged;
  // May throw: the frame's turn stays.
  if (traced) {
    analyzer_.AddTraced(frame, *traced, &unchanged);
  } else {
    analyzer_.Add(frame, &unchanged);
  }
  return ChangeMask{nextFrame_++, std::move(unchanged)};
}

JobCoherence::ChangeMask JobCoherence::TakeInOrder(const FrameChanges& frame) {
  std::vector<uint8_t> unchanged;
  analyzer_.AddChanges(frame, &unchanged);  // may throw: the frame's turn stays
  return ChangeMask{nextFrame_++, std::move(unchanged)};
}

}  // namespace tcfarm
