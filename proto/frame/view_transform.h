// How a frame's linear values become the 8-bit sRGB codes of its PNG preview: the view
// transform. The EXR master is always the linear values themselves; only the preview,
// which people look at, is viewed.
//
//   standard         clamp to [0, 1], then the sRGB encoding (the farm's first preview)
//   khr-pbr-neutral  the Khronos PBR Neutral tone mapper, then the sRGB encoding: base
//                    colours in [0.08, 0.8] keep their value (less a 0.04 offset) and
//                    highlights roll off towards white instead of clipping
//
// Exposure scales the linear values by 2^EV before either.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace tcfarm {

enum class View { kStandard, kKhrPbrNeutral };

struct ViewTransform {
  View view = View::kStandard;
  double exposure = 0;  // stops (EV): values are scaled by 2^exposure first
  bool IsDefault() const { return view == View::kStandard && exposure == 0; }
  bool operator==(const ViewTransform& other) const { return view == other.view && exposure == other.exposure; }
};

// Exposures outside [-kMaxExposure, kMaxExposure] are refused: beyond them every value
// of a frame clips to black or white either way.
constexpr double kMaxExposure = 32;

// "standard", "khr-pbr-neutral".
std::string_view ViewName(View view);
// The view named `name`; nullopt for a name that is none.
std::optional<View> ParseView(std::string_view name);
// "standard, khr-pbr-neutral", for messages.
std::string ViewNames();
// Whether `exposure` is a finite number in [-kMaxExposure, kMaxExposure].
bool IsValidExposure(double exposure);

// The Khronos PBR Neutral tone mapper (github.com/KhronosGroup/ToneMapping, PBR_Neutral):
// non-negative linear Rec. 709 in, linear Rec. 709 in [0, 1] out. Negative and NaN
// channels count as 0, +infinity as the largest float.
std::array<float, 3> KhrPbrNeutral(std::array<float, 3> rgb);

// The image's linear RGB (width * height * 3 values) as 8-bit sRGB codes through `view`.
// The default view gives exactly LinearToSrgb8Fast of every value.
std::vector<uint8_t> DisplayCodes(const std::vector<float>& rgb, const ViewTransform& view);

}  // namespace tcfarm
