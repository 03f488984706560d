// Small geometry that importers share: vector arithmetic in double and the scene parser's
// own test for a mesh with area, so an imported scene always reads back through ParseScene
// (workers receive it as JSON).
#pragma once

#include <cmath>

#include "proto/scene/scene.h"

namespace tcfarm::import {

inline Vec3 Sub(const Vec3& a, const Vec3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline double Norm(const Vec3& v) { return std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z); }
inline Vec3 CrossProduct(const Vec3& a, const Vec3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

// As the scene parser: a triangle whose area is below this share of its edges' product has
// none, and a mesh needs one triangle with area.
bool HasArea(const TriangleMesh& mesh);

}  // namespace tcfarm::import
