// Ray cones: how wide a pixel's ray is where it meets a surface, so that glTF textures are
// filtered over what the pixel covers (the method of Akenine-Moller et al., "Texture Level
// of Detail Strategies for Real-Time Ray Tracing", Ray Tracing Gems, 2019). The cone is
// the pixel's own, computed from its camera ray alone, never from neighbouring pixels'
// hits (as screen-space derivatives would be): a pixel's bits stay its own, whichever
// pixels are traced with it.
#pragma once

#include <array>
#include <cstdint>
#include <limits>

namespace tcfarm {

struct RayCone {
  float width = 0;   // across the cone where the ray starts
  float spread = 0;  // radians: the width grows by spread x distance travelled
  float WidthAt(float distance) const { return width + spread * distance; }
};

// Where a cone meets a triangle: log2 of its width in texture coordinates, for each
// coordinate set (uvs, uvs1). -inf (a point) samples the full image.
struct UvFootprint {
  static constexpr float kPoint = -std::numeric_limits<float>::infinity();
  std::array<float, 2> log2Width{kPoint, kPoint};
};

// log2 of the width in texture coordinates that a cone `coneWidth` wide covers where it
// meets a triangle whose unit normal makes `cosine` with the ray, the triangle spanning
// `uvArea` of its texture coordinates for `worldArea` of the world (any one multiple of
// the two areas). The cone's cross-section stretched by 1 / |cosine| over the surface,
// scaled by the triangle's texel density. kPoint where the cone has no width or the
// triangle no area.
float Log2UvWidth(float coneWidth, float cosine, double uvArea, double worldArea);

// Twice the area that triangle `corner` spans of texture coordinates `uvs`.
double UvArea2(const std::array<float, 2>* uvs, const std::array<uint32_t, 3>& corner);

}  // namespace tcfarm
