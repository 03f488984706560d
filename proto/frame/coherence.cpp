#include "proto/frame/coherence.h"

#include <algorithm>
#include <cstdio>
#include <stdexcept>

#include "proto/frame/compare.h"

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

std::string CoherenceSummary(const RunningStats& frameToFrame, const RunningStats& longTerm) {
  if (frameToFrame.count == 0) return "coherence: needs at least two frames";
  char text[256];
  std::snprintf(text, sizeof text,
                "coherence: frame-to-frame mean %.2f%% (min %.2f%%, max %.2f%%), "
                "long-term mean %.2f%% (min %.2f%%, max %.2f%%)",
                100 * frameToFrame.Mean(), 100 * frameToFrame.min, 100 * frameToFrame.max,
                100 * longTerm.Mean(), 100 * longTerm.min, 100 * longTerm.max);
  return text;
}

}  // namespace tcfarm
