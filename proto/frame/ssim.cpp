#include "proto/frame/ssim.h"

#include <algorithm>
#include <stdexcept>
#include <string>
#include <vector>

namespace tcfarm {
namespace {

constexpr int kWindowSide = 8;        // pixels; Wang et al. 2004, Section III-C
constexpr double kC1 = 0.01 * 0.01;   // (K1 L)^2 with K1 = 0.01, L = 1
constexpr double kC2 = 0.03 * 0.03;   // (K2 L)^2 with K2 = 0.03, L = 1

void CheckPair(const Image& reference, const Image& test) {
  auto text = [](const Image& image) {
    return std::to_string(image.width) + "x" + std::to_string(image.height);
  };
  if (reference.width != test.width || reference.height != test.height) {
    throw std::invalid_argument("SSIM of a " + text(test) + " image against a " +
                                text(reference) + " reference");
  }
  for (const Image* image : {&reference, &test}) {
    if (image->width <= 0 || image->height <= 0 ||
        image->rgb.size() != image->PixelCount() * 3) {
      throw std::invalid_argument("SSIM of an empty or malformed " + text(*image) + " image");
    }
  }
}

// Displayed luma in [0, 1]: the 8-bit sRGB codes the PNG holds, Rec. 709 weights.
std::vector<double> DisplayedLuma(const Image& image) {
  std::vector<double> luma(image.PixelCount());
  for (size_t p = 0; p < luma.size(); ++p) {
    const float* rgb = &image.rgb[3 * p];
    luma[p] = (0.2126 * LinearToSrgb8Fast(rgb[0]) + 0.7152 * LinearToSrgb8Fast(rgb[1]) +
               0.0722 * LinearToSrgb8Fast(rgb[2])) / 255.0;
  }
  return luma;
}

// Sums of x, y, x^2, y^2 and xy over one window.
struct WindowSums {
  double x = 0, y = 0, xx = 0, yy = 0, xy = 0;
  void Add(const WindowSums& other) {
    x += other.x;
    y += other.y;
    xx += other.xx;
    yy += other.yy;
    xy += other.xy;
  }
};

// [row][column] = sums over the windowWidth pixels of the row starting at column. Summed
// afresh for each window, not slid, so no rounding drifts along the row.
std::vector<WindowSums> RowSums(const std::vector<double>& x, const std::vector<double>& y,
                                int width, int height, int windowWidth) {
  const int columns = width - windowWidth + 1;
  std::vector<WindowSums> sums(static_cast<size_t>(columns) * height);
  for (int row = 0; row < height; ++row) {
    for (int column = 0; column < columns; ++column) {
      WindowSums& s = sums[static_cast<size_t>(row) * columns + column];
      for (int i = 0; i < windowWidth; ++i) {
        size_t p = static_cast<size_t>(row) * width + column + i;
        s.Add({x[p], y[p], x[p] * x[p], y[p] * y[p], x[p] * y[p]});
      }
    }
  }
  return sums;
}

double WindowSsim(const WindowSums& sums, double count) {
  double muX = sums.x / count, muY = sums.y / count;
  double varX = sums.xx / count - muX * muX;
  double varY = sums.yy / count - muY * muY;
  double covariance = sums.xy / count - muX * muY;
  return (2 * muX * muY + kC1) * (2 * covariance + kC2) /
         ((muX * muX + muY * muY + kC1) * (varX + varY + kC2));
}

}  // namespace

double Ssim(const Image& reference, const Image& test) {
  CheckPair(reference, test);
  const int width = reference.width, height = reference.height;
  const int windowWidth = std::min(kWindowSide, width);
  const int windowHeight = std::min(kWindowSide, height);
  const int columns = width - windowWidth + 1, rows = height - windowHeight + 1;
  std::vector<WindowSums> rowSums = RowSums(DisplayedLuma(reference), DisplayedLuma(test),
                                            width, height, windowWidth);
  const double count = double(windowWidth) * windowHeight;
  double total = 0;
  for (int row = 0; row < rows; ++row) {
    for (int column = 0; column < columns; ++column) {
      WindowSums window;
      for (int i = 0; i < windowHeight; ++i) {
        window.Add(rowSums[static_cast<size_t>(row + i) * columns + column]);
      }
      total += WindowSsim(window, count);
    }
  }
  return total / (double(rows) * columns);
}

}  // namespace tcfarm
