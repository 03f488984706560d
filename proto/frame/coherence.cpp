#include "frame/coherence.h"

#include <algorithm>
#include <cstdio>
#include <stdexcept>

#include "frame/compare.h"

namespace tcfarm {

double Coherence(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height) {
    throw std::invalid_argument("coherence of frames of different sizes: " +
                                std::to_string(a.width) + "x" + std::to_string(a.height) +
                                " and " + std::to_string(b.width) + "x" +
                                std::to_string(b.height));
  }
  size_t pixels = a.PixelCount(), equal = 0;
  for (size_t i = 0; i < pixels; ++i) {
    // Bitwise, not ==: the farm copies bits, so coherence must count identical bits.
    equal += SameBits(&a.rgb[3 * i], &b.rgb[3 * i]);
  }
  return pixels ? static_cast<double>(equal) / pixels : 1.0;
}

void RunningStats::Add(double value) {
  min = count ? std::min(min, value) : value;
  max = count ? std::max(max, value) : value;
  sum += value;
  ++count;
}

void CoherenceTracker::Add(const Image& frame) {
  if (!haveFirst_) {
    first_ = previous_ = frame;
    haveFirst_ = true;
    return;
  }
  frameToFrame_.Add(Coherence(previous_, frame));
  longTerm_.Add(Coherence(first_, frame));
  previous_ = frame;
}

std::string CoherenceTracker::Summary() const {
  if (frameToFrame_.count == 0) return "coherence: needs at least two frames";
  char text[256];
  std::snprintf(text, sizeof text,
                "coherence: frame-to-frame mean %.2f%% (min %.2f%%, max %.2f%%), "
                "long-term mean %.2f%% (min %.2f%%, max %.2f%%)",
                100 * frameToFrame_.Mean(), 100 * frameToFrame_.min, 100 * frameToFrame_.max,
                100 * longTerm_.Mean(), 100 * longTerm_.min, 100 * longTerm_.max);
  return text;
}

}  // namespace tcfarm
