// A per-vertex value at a hit on a triangle: its three corners weighted by the hit's
// barycentric coordinates (u, v), as Embree reports them. One home for the sum, so every
// reader of texture coordinates and vertex colours rounds it the same way.
#pragma once

#include <array>
#include <cstdint>

#include "worker/trace/float3.h"

namespace tcfarm {

inline std::array<float, 2> AtBarycentric(const std::array<float, 2>* values, const std::array<uint32_t, 3>& corner,
                                          float u, float v) {
  const float w = 1.0f - u - v;
  const auto &a = values[corner[0]], &b = values[corner[1]], &c = values[corner[2]];
  return {a[0] * w + b[0] * u + c[0] * v, a[1] * w + b[1] * u + c[1] * v};
}

inline Float3 AtBarycentric(const Float3* values, const std::array<uint32_t, 3>& corner, float u, float v) {
  const float w = 1.0f - u - v;
  return values[corner[0]] * w + values[corner[1]] * u + values[corner[2]] * v;
}

}  // namespace tcfarm
