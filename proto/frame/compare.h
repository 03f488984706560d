// Error of a frame against its reference (the brute-force render): the paper's metric,
// pixels differing, plus the size of the differences.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>

#include "proto/frame/frame_io.h"

namespace tcfarm {

// Whether two pixels (3 floats of linear RGB each) have the same bits: the farm copies
// bits, so equality is bitwise everywhere (-0 differs from +0, a NaN may equal itself).
inline bool SameBits(const float* a, const float* b) { return std::memcmp(a, b, 3 * sizeof(float)) == 0; }

struct FrameError {
  uint64_t pixels = 0;
  uint64_t differingPixels = 0;  // any channel's bits differ
  double maxAbsError = 0;        // largest channel difference, linear
  double squaredErrorSum = 0;    // over channels, values clamped to [0, 1] as displayed

  FrameError& operator+=(const FrameError& other);
  double DifferingShare() const { return pixels ? double(differingPixels) / pixels : 0; }
  // Peak signal-to-noise ratio over [0, 1]; infinity when identical.
  double Psnr() const;
};

// Throws std::invalid_argument when the sizes differ.
FrameError CompareImages(const Image& reference, const Image& test);

}  // namespace tcfarm
