// Image-space coherence of a frame sequence (paper, section 2): the share of pixels whose
// value is bit-for-bit equal between two frames. Frame-to-frame compares f with f+1;
// long-term compares the first frame with each later one.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "proto/frame/frame_io.h"

namespace tcfarm {

// Share of pixels in [0, 1] whose three channels are bitwise equal.
double Coherence(const Image& a, const Image& b);

struct RunningStats {
  size_t count = 0;
  double sum = 0, min = 0, max = 0;
  void Add(double value);
  double Mean() const { return count ? sum / count : 0; }
};

// "coherence: frame-to-frame mean 95.06% (min 91.57%, max 97.48%), long-term ..." for the
// running figures of a sequence (SequenceAnalyzer keeps them while frames arrive).
std::string CoherenceSummary(const RunningStats& frameToFrame, const RunningStats& longTerm);

}  // namespace tcfarm
