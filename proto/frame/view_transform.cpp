#include "proto/frame/view_transform.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "proto/frame/frame_io.h"

namespace tcfarm {
namespace {

struct ViewNameEntry {
  View view;
  std::string_view name;
};
constexpr ViewNameEntry kViewNames[] = {{View::kStandard, "standard"}, {View::kKhrPbrNeutral, "khr-pbr-neutral"}};

// The tone mapper's constants, as Khronos names them.
constexpr float kF90 = 0.04f;                    // Fresnel reflectance at normal incidence (IoR 1.5)
constexpr float kStartCompression = 0.8f - kF90;  // K_s: where highlight compression starts
constexpr float kDesaturation = 0.15f;            // K_d: how fast compressed highlights go white

// The mapper is defined for non-negative input; a NaN or negative channel (never traced,
// but an EXR may be edited) is black, and +infinity saturates instead of making NaN.
float Admissible(float value) {
  if (!(value > 0)) return 0;
  return std::min(value, std::numeric_limits<float>::max());
}

}  // namespace

std::string_view ViewName(View view) {
  for (const ViewNameEntry& entry : kViewNames) {
    if (entry.view == view) return entry.name;
  }
  return "standard";
}

std::optional<View> ParseView(std::string_view name) {
  for (const ViewNameEntry& entry : kViewNames) {
    if (entry.name == name) return entry.view;
  }
  return std::nullopt;
}

std::string ViewNames() {
  std::string names;
  for (const ViewNameEntry& entry : kViewNames) names += (names.empty() ? "" : ", ") + std::string(entry.name);
  return names;
}

bool IsValidExposure(double exposure) { return std::isfinite(exposure) && std::fabs(exposure) <= kMaxExposure; }

std::array<float, 3> KhrPbrNeutral(std::array<float, 3> rgb) {
  for (float& channel : rgb) channel = Admissible(channel);
  // Shadows: a small offset, fading in quadratically so that black stays black.
  const float x = std::min({rgb[0], rgb[1], rgb[2]});
  const float offset = x < 2 * kF90 ? x - 6.25f * x * x : kF90;  // 6.25 = 1 / (4 F90)
  for (float& channel : rgb) channel -= offset;
  const float peak = std::max({rgb[0], rgb[1], rgb[2]});
  if (peak < kStartCompression) return rgb;
  // Highlights: the peak rolls off towards 1, and the colour towards white as it does.
  const float d = 1 - kStartCompression;
  const float newPeak = 1 - d * d / (peak + d - kStartCompression);
  const float toWhite = 1 - 1 / (kDesaturation * (peak - newPeak) + 1);
  for (float& channel : rgb) {
    const float compressed = channel * (newPeak / peak);
    channel = compressed * (1 - toWhite) + newPeak * toWhite;  // GLSL's mix(compressed, newPeak, toWhite)
  }
  return rgb;
}

std::vector<uint8_t> DisplayCodes(const std::vector<float>& rgb, const ViewTransform& view) {
  std::vector<uint8_t> codes(rgb.size());
  if (view.IsDefault()) {  // the farm's first preview, bit for bit
    std::transform(rgb.begin(), rgb.end(), codes.begin(), LinearToSrgb8Fast);
    return codes;
  }
  const float scale = static_cast<float>(std::exp2(view.exposure));
  for (size_t at = 0; at + 2 < rgb.size(); at += 3) {
    std::array<float, 3> pixel{rgb[at] * scale, rgb[at + 1] * scale, rgb[at + 2] * scale};
    if (view.view == View::kKhrPbrNeutral) pixel = KhrPbrNeutral(pixel);
    for (int c = 0; c < 3; ++c) codes[at + c] = LinearToSrgb8Fast(pixel[c]);
  }
  return codes;
}

}  // namespace tcfarm
