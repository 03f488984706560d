// Small geometry that importers share: vector arithmetic in double and the scene parser's
// own test for a mesh with area, so an imported scene always reads back through ParseScene
// (workers receive it as JSON).
#pragma once

#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "proto/scene/scene.h"
#include "proto/scene/scene_limits.h"

namespace tcfarm::import {

inline Vec3 Sub(const Vec3& a, const Vec3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline double Norm(const Vec3& v) { return std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z); }
// v made unit; zero stays zero.
inline Vec3 Normalized(const Vec3& v) {
  const double length = Norm(v);
  return length > 0 ? Vec3{v.x / length, v.y / length, v.z / length} : v;
}
inline Vec3 CrossProduct(const Vec3& a, const Vec3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

// As the scene parser: a triangle whose area is below this share of its edges' product has
// none, and a mesh needs one triangle with area.
bool HasArea(const TriangleMesh& mesh);

// An axis-aligned box grown point by point; empty until the first point.
struct BoundingBox {
  Vec3 low{scene_limits::kMaxMagnitude, scene_limits::kMaxMagnitude, scene_limits::kMaxMagnitude};
  Vec3 high{-scene_limits::kMaxMagnitude, -scene_limits::kMaxMagnitude, -scene_limits::kMaxMagnitude};
  void Add(const Vec3& point);
  void Add(const std::vector<Vec3>& points);
  bool Empty() const { return low.x > high.x; }
  std::array<Vec3, 8> Corners() const;
};

// The camera a file without one gets (OBJ, glTF): from the front (+z, the usual facing) and
// a little above, at the scene format's default 45 degrees, far enough that the box's
// bounding sphere fits with a margin; an empty box is framed at the origin. Refused, naming
// `displayName`, when it would stand beyond the scene's magnitude limit.
constexpr double kFramingFovDegrees = 45;
CameraPose FramingPose(const BoundingBox& box, const std::string& displayName);

// The light a file without any gets travels along this, in the default camera's view: from
// above and behind its right shoulder, so the faces it sees are lit.
inline const Vec3 kDefaultLightDirection{-0.4, -1, -0.7};

}  // namespace tcfarm::import
