#include "farm/job_coherence.h"

#include <utility>

#include "frame/compare.h"

namespace tcfarm {

JobCoherence::JobCoherence(int width, int height, std::filesystem::path spillFolder,
                                   size_t pendingFrameBytes)
    : width_(width), height_(height), waiting_(std::move(spillFolder), pendingFrameBytes) {}

std::vector<JobCoherence::ChangeMask> JobCoherence::Add(int frame, const std::vector<float>& rgb) {
  std::vector<ChangeMask> masks;
  Image image{width_, height_, rgb};
  if (frame != nextFrame_) {
    waiting_.Put(frame, std::move(image));
    return masks;
  }
  masks.push_back(TakeInOrder(std::move(image)));
  while (std::optional<Image> next = waiting_.Take(nextFrame_)) masks.push_back(TakeInOrder(std::move(*next)));
  return masks;
}

// The first frame has nothing to change from, so its mask is all white.
JobCoherence::ChangeMask JobCoherence::TakeInOrder(Image frame) {
  analyzer_.Add(frame);
  const std::vector<float>& current = frame.rgb;
  std::vector<uint8_t> unchanged(frame.PixelCount(), 1);
  if (previousRgb_.size() == current.size()) {
    for (size_t pixel = 0; pixel < unchanged.size(); ++pixel) {
      unchanged[pixel] = SameBits(&current[pixel * 3], &previousRgb_[pixel * 3]);
    }
  }
  previousRgb_ = std::move(frame.rgb);
  return ChangeMask{nextFrame_++, std::move(unchanged)};
}

}  // namespace tcfarm
