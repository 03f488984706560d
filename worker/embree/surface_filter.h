// Which hits of a shape count, beyond its geometry: a material's alpha mask and back-face
// culling (glTF's alphaMode MASK and doubleSided false). Embree asks a shape's filter for
// every candidate hit, in every query that traverses it: camera, shadow, secondary rays
// and the horizons' re-tests of frames ahead, so every path sees the same surface.
#pragma once

#include <embree3/rtcore.h>

namespace tcfarm {

class SurfaceRule {
 public:
  virtual ~SurfaceRule() = default;
  // Whether the hit at barycentric (u, v) of triangle `primitive` counts. backFace: the ray
  // meets the triangle's back, against its counter-clockwise normal. occlusion: a shadow
  // ray's query (it sees both faces: a one-sided surface still casts its shadow).
  // Deterministic: Embree may ask twice for one hit.
  virtual bool Keeps(unsigned primitive, float u, float v, bool backFace, bool occlusion) const = 0;
};

// What a geometry's filter callbacks are given: the shape's rule (null: none) and whether
// the scene's tie rule applies (closest_hit.h).
struct SurfaceFilter {
  const SurfaceRule* rule = nullptr;
  bool settleTies = false;
};

// Sets the geometry's callbacks: the rule and then the tie rule for closest hits, the rule
// for occlusion. `filter` must outlive the geometry.
void SetSurfaceFilters(RTCGeometry geometry, const SurfaceFilter* filter);

}  // namespace tcfarm
