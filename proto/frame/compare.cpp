#include "proto/frame/compare.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>

namespace tcfarm {
namespace {

// Reads the frame in place; compare never writes to its inputs.
OIIO::ImageBuf WrapForReading(const Image& image) {
  return OIIO::ImageBuf(OIIO::ImageSpec(image.width, image.height, 3, OIIO::TypeDesc::FLOAT),
                        const_cast<float*>(image.rgb.data()));
}

}  // namespace

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
  // The paper's metric counts bits, which no image library does: -0 against +0 differs.
  // The squared error stays ours too, rather than OIIO's PSNR: that one takes the values
  // unclamped and measures against its own peak, so on the HDR frames tracing produces it
  // disagrees with ours (22 dB against 17 dB on a pair of rendered frames), and a sequence's
  // PSNR needs the frames' error sums, not their PSNRs.
  for (size_t p = 0; p < error.pixels; ++p) {
    const float* a = &reference.rgb[3 * p];
    const float* b = &test.rgb[3 * p];
    if (SameBits(a, b)) continue;
    ++error.differingPixels;
    for (int c = 0; c < 3; ++c) {
      double d = std::clamp(double(a[c]), 0.0, 1.0) - std::clamp(double(b[c]), 0.0, 1.0);
      error.squaredErrorSum += d * d;
    }
  }
  // Identical frames, the common case, skip a second pass. OIIO takes the difference in
  // float, so it can be one float rounding off the exact one (0.25 for 0.2500000037).
  if (error.differingPixels != 0) {
    // compare reports any value beyond failthresh as an error; with no threshold, its error
    // flag means only that the images could not be compared.
    constexpr float kNoThreshold = std::numeric_limits<float>::infinity();
    OIIO::ImageBuf referenceBuffer = WrapForReading(reference);
    const OIIO::ImageBufAlgo::CompareResults compared = OIIO::ImageBufAlgo::compare(
        referenceBuffer, WrapForReading(test), kNoThreshold, kNoThreshold);
    if (compared.error) {
      throw std::runtime_error("cannot compare frames: " + referenceBuffer.geterror());
    }
    error.maxAbsError = compared.maxerror;
  }
  return error;
}

}  // namespace tcfarm
