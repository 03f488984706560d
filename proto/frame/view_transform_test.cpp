#include "proto/frame/view_transform.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include "proto/frame/frame_io.h"

namespace tcfarm {
namespace {

using Rgb = std::array<float, 3>;

// The tone mapper as its specification writes it (KhronosGroup/ToneMapping, PBR_Neutral
// README), in double: F90 = 0.04, Ks = 0.8 - F90, Kd = 0.15;
//   x = min(R, G, B);  f = x - x^2 / (4 F90) for x <= 2 F90, else F90
//   p = max(c - f);    pn = 1 - (1 - Ks)^2 / (p + 1 - 2 Ks);  g = 1 / (Kd (p - pn) + 1)
//   out = c - f for p <= Ks, else (c - f) pn / p g + pn (1 - g).
std::array<double, 3> Specification(const Rgb& in) {
  const double f90 = 0.04, ks = 0.8 - f90, kd = 0.15;
  const double x = std::min({in[0], in[1], in[2]});
  const double f = x <= 2 * f90 ? x - x * x / (4 * f90) : f90;
  std::array<double, 3> shifted{in[0] - f, in[1] - f, in[2] - f};
  const double p = std::max({shifted[0], shifted[1], shifted[2]});
  if (p <= ks) return shifted;
  const double pn = 1 - (1 - ks) * (1 - ks) / (p + 1 - 2 * ks);
  const double g = 1 / (kd * (p - pn) + 1);
  for (double& channel : shifted) channel = channel * pn / p * g + pn * (1 - g);
  return shifted;
}

void ExpectMatchesSpecification(const Rgb& in) {
  const Rgb out = KhrPbrNeutral(in);
  const std::array<double, 3> expected = Specification(in);
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(out[c], expected[c], 2e-6) << "channel " << c << " of " << in[0] << ", " << in[1] << ", " << in[2];
  }
}

TEST(KhrPbrNeutralTest, BaseColoursKeepTheirValueLessTheOffset) {
  // Below the compression start, with every channel in [0.08, 0.8]: c - 0.04, nothing else.
  for (const Rgb& in : {Rgb{0.08f, 0.5f, 0.8f}, Rgb{0.3f, 0.3f, 0.3f}, Rgb{0.79f, 0.1f, 0.45f}}) {
    const Rgb out = KhrPbrNeutral(in);
    for (int c = 0; c < 3; ++c) EXPECT_FLOAT_EQ(out[c], in[c] - 0.04f);
  }
}

TEST(KhrPbrNeutralTest, DarkColoursTakeTheQuadraticOffset) {
  // min < 0.08: the offset x - x^2 / 0.16 fades to 0 at black, so black stays black.
  EXPECT_EQ(KhrPbrNeutral({0, 0, 0}), (Rgb{0, 0, 0}));
  for (const Rgb& in : {Rgb{0.02f, 0.2f, 0.5f}, Rgb{0.0f, 0.4f, 0.1f}, Rgb{0.05f, 0.05f, 0.05f}}) {
    ExpectMatchesSpecification(in);
    const double x = std::min({in[0], in[1], in[2]});
    EXPECT_NEAR(KhrPbrNeutral(in)[1], in[1] - (x - x * x / 0.16), 1e-7);
  }
}

TEST(KhrPbrNeutralTest, HighlightsFollowTheFormula) {
  for (const Rgb& in : {Rgb{0.9f, 0.5f, 0.2f}, Rgb{1, 1, 1}, Rgb{2.5f, 0.3f, 0.1f}, Rgb{10, 20, 5},
                        Rgb{100, 0, 0}, Rgb{0.81f, 0.81f, 0.81f}}) {
    ExpectMatchesSpecification(in);
  }
}

TEST(KhrPbrNeutralTest, OutputStaysInTheUnitRangeAndLargeValuesGoWhite) {
  const Rgb bright = KhrPbrNeutral({1e6f, 1e5f, 0});
  for (float channel : bright) {
    EXPECT_GT(channel, 0.999f);
    EXPECT_LE(channel, 1.0f);
  }
  const float inf = std::numeric_limits<float>::infinity();
  for (float channel : KhrPbrNeutral({inf, 0, 0})) EXPECT_TRUE(channel >= 0 && channel <= 1) << channel;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(KhrPbrNeutral({nan, -1, 0}), (Rgb{0, 0, 0}));  // not light: black
}

TEST(KhrPbrNeutralTest, IsMonotonicAlongGreyAndColouredRamps) {
  for (const Rgb& hue : {Rgb{1, 1, 1}, Rgb{1, 0.5f, 0.1f}, Rgb{0.2f, 0.3f, 1}}) {
    Rgb previous = KhrPbrNeutral({0, 0, 0});
    for (float scale = 0.001f; scale < 1000; scale *= 1.01f) {
      const Rgb out = KhrPbrNeutral({hue[0] * scale, hue[1] * scale, hue[2] * scale});
      // The brightest channel never falls, and none leaves [0, 1].
      const int brightest = static_cast<int>(std::max_element(hue.begin(), hue.end()) - hue.begin());
      EXPECT_GE(out[brightest], previous[brightest]) << "at scale " << scale;
      for (float channel : out) EXPECT_TRUE(channel >= 0 && channel <= 1) << channel << " at scale " << scale;
      previous = out;
    }
  }
}

TEST(ViewTransformTest, NamesRoundTrip) {
  for (View view : {View::kStandard, View::kKhrPbrNeutral}) EXPECT_EQ(ParseView(ViewName(view)), view);
  EXPECT_EQ(ParseView("filmic"), std::nullopt);
  EXPECT_EQ(ViewNames(), "standard, khr-pbr-neutral");
  EXPECT_TRUE(IsValidExposure(-3.5));
  EXPECT_FALSE(IsValidExposure(kMaxExposure + 1));
  EXPECT_FALSE(IsValidExposure(std::nan("")));
}

TEST(ViewTransformTest, StandardIsTheClampedSrgbEncodingAndExposureScalesFirst) {
  const std::vector<float> rgb{-1, 0, 0.001f, 0.2f, 0.5f, 0.9f, 1, 3, std::nanf("")};
  std::vector<uint8_t> codes = DisplayCodes(rgb, {});
  for (size_t i = 0; i < rgb.size(); ++i) EXPECT_EQ(codes[i], LinearToSrgb8Fast(rgb[i])) << i;
  codes = DisplayCodes(rgb, {View::kStandard, 1});
  for (size_t i = 0; i < rgb.size(); ++i) EXPECT_EQ(codes[i], LinearToSrgb8Fast(rgb[i] * 2)) << i;
}

TEST(ViewTransformTest, NeutralEncodesTheToneMappedValues) {
  const std::vector<float> rgb{0.3f, 0.5f, 0.7f, 4, 2, 1};
  const ViewTransform view{View::kKhrPbrNeutral, -1};
  const std::vector<uint8_t> codes = DisplayCodes(rgb, view);
  for (size_t pixel = 0; pixel < 2; ++pixel) {
    const float* in = &rgb[pixel * 3];
    const Rgb mapped = KhrPbrNeutral({in[0] / 2, in[1] / 2, in[2] / 2});
    for (int c = 0; c < 3; ++c) EXPECT_EQ(codes[pixel * 3 + c], LinearToSrgb8Fast(mapped[c]));
  }
  EXPECT_NE(codes, DisplayCodes(rgb, {}));
}

}  // namespace
}  // namespace tcfarm
