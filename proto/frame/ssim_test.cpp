#include "proto/frame/ssim.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>

namespace tcfarm {
namespace {

// A scene-like image: smooth shading with an edge, so windows have structure.
Image Scene(int width, int height) {
  Image image{width, height, std::vector<float>(static_cast<size_t>(width) * height * 3)};
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      float shade = 0.1f + 0.6f * x / width + (x > width / 2 ? 0.2f : 0.0f);
      for (int c = 0; c < 3; ++c) {
        image.rgb[3 * (static_cast<size_t>(y) * width + x) + c] = shade * (0.6f + 0.2f * c);
      }
    }
  }
  return image;
}

Image WithNoise(const Image& image, float amplitude, unsigned seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<float> noise(-1, 1);
  Image noisy = image;
  for (float& v : noisy.rgb) v = std::max(0.0f, v + amplitude * noise(random));
  return noisy;
}

TEST(SsimTest, IdenticalImagesScoreExactlyOne) {
  Image image = Scene(40, 30);
  EXPECT_EQ(Ssim(image, image), 1.0);
  Image flat{9, 9, std::vector<float>(9 * 9 * 3, 0.0f)};
  EXPECT_EQ(Ssim(flat, flat), 1.0);  // C1 and C2 keep black on black defined
}

TEST(SsimTest, DifferencesBelowOneDisplayedCodeAreInvisible) {
  Image image = Scene(16, 16), nudged = image;
  nudged.rgb[10] = std::nextafter(nudged.rgb[10], 1.0f);  // same 8-bit code
  EXPECT_EQ(Ssim(image, nudged), 1.0);
}

TEST(SsimTest, ConstantOffsetLowersIt) {
  Image image = Scene(40, 30), brighter = image;
  for (float& v : brighter.rgb) v += 0.2f;
  double ssim = Ssim(image, brighter);
  EXPECT_LT(ssim, 1.0);
  EXPECT_GT(ssim, 0.5);  // a luminance shift keeps the structure: still fairly similar
}

TEST(SsimTest, FallsMonotonicallyWithNoiseAmplitude) {
  Image image = Scene(48, 40);
  double previous = 1.0;
  for (float amplitude : {0.005f, 0.01f, 0.02f, 0.05f, 0.1f, 0.2f, 0.4f}) {
    double ssim = Ssim(image, WithNoise(image, amplitude, 7));
    EXPECT_LT(ssim, previous) << amplitude;
    previous = ssim;
  }
  EXPECT_LT(previous, 0.5);
}

TEST(SsimTest, IsSymmetric) {
  Image image = Scene(33, 21), noisy = WithNoise(image, 0.05f, 3);
  EXPECT_EQ(Ssim(image, noisy), Ssim(noisy, image));
}

TEST(SsimTest, HandlesImagesSmallerThanTheWindow) {
  Image image = Scene(5, 3), noisy = WithNoise(image, 0.1f, 5);
  EXPECT_EQ(Ssim(image, image), 1.0);
  double ssim = Ssim(image, noisy);
  EXPECT_LT(ssim, 1.0);
  EXPECT_GT(ssim, -1.0);
}

TEST(SsimTest, MatchesTheFormulaOnOneWindow) {
  // An 8x8 image is one window: check against the formula computed by hand.
  Image x = Scene(8, 8), y = WithNoise(x, 0.1f, 11);
  auto luma = [](const Image& image, size_t p) {
    return (0.2126 * LinearToSrgb8Fast(image.rgb[3 * p]) +
            0.7152 * LinearToSrgb8Fast(image.rgb[3 * p + 1]) +
            0.0722 * LinearToSrgb8Fast(image.rgb[3 * p + 2])) / 255.0;
  };
  double muX = 0, muY = 0;
  for (size_t p = 0; p < 64; ++p) {
    muX += luma(x, p) / 64;
    muY += luma(y, p) / 64;
  }
  double varX = 0, varY = 0, cov = 0;
  for (size_t p = 0; p < 64; ++p) {
    varX += (luma(x, p) - muX) * (luma(x, p) - muX) / 64;
    varY += (luma(y, p) - muY) * (luma(y, p) - muY) / 64;
    cov += (luma(x, p) - muX) * (luma(y, p) - muY) / 64;
  }
  const double c1 = 1e-4, c2 = 9e-4;
  double expected = (2 * muX * muY + c1) * (2 * cov + c2) /
                    ((muX * muX + muY * muY + c1) * (varX + varY + c2));
  EXPECT_NEAR(Ssim(x, y), expected, 1e-9);
}

TEST(SsimTest, RejectsMismatchedOrEmptyImages) {
  EXPECT_THROW(Ssim(Scene(8, 8), Scene(8, 9)), std::invalid_argument);
  EXPECT_THROW(Ssim(Image{}, Image{}), std::invalid_argument);
  Image malformed = Scene(4, 4);
  malformed.rgb.pop_back();
  EXPECT_THROW(Ssim(malformed, malformed), std::invalid_argument);
}

}  // namespace
}  // namespace tcfarm
