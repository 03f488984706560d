#include "frame/compare.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>

namespace tcfarm {

FrameError& FrameError::operator+=(const FrameError& other) {
  pixels += other.pixels;
  differingPixels += other.differingPixels;
  maxAbsError = std::max(maxAbsError, other.maxAbsError);
  squaredErrorSum += other.squaredErrorSum;
  return *this;
}

double FrameError::Psnr() const {
  if (squaredErrorSum == 0) return std::numeric_limits<double>::infinity();
  double mse = squaredErrorSum / (3.0 * pixels);
  return 10.0 * std::log10(1.0 / mse);
}

FrameError CompareImages(const Image& reference, const Image& test) {
  if (reference.width != test.width || reference.height != test.height ||
      reference.rgb.size() != test.rgb.size()) {
    throw std::invalid_argument("cannot compare a " + std::to_string(test.width) + "x" +
                                std::to_string(test.height) + " frame with a " +
                                std::to_string(reference.width) + "x" +
                                std::to_string(reference.height) + " reference");
  }
  FrameError error;
  error.pixels = reference.PixelCount();
  for (size_t p = 0; p < error.pixels; ++p) {
    const float* a = &reference.rgb[3 * p];
    const float* b = &test.rgb[3 * p];
    if (std::memcmp(a, b, 3 * sizeof(float)) == 0) continue;
    ++error.differingPixels;
    for (int c = 0; c < 3; ++c) {
      error.maxAbsError = std::max(error.maxAbsError, std::fabs(double(a[c]) - double(b[c])));
      double d = std::clamp(double(a[c]), 0.0, 1.0) - std::clamp(double(b[c]), 0.0, 1.0);
      error.squaredErrorSum += d * d;
    }
  }
  return error;
}

}  // namespace tcfarm
