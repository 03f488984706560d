#include "worker/shapes/shape_kind.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace tcfarm {

const ShapeKind& KindOf(const Shape& shape) {
#define TCFARM_SHAPE_KIND_ENTRY(Stem) &Stem##Kind(),
  static const std::array<const ShapeKind*, Shape::kTypeCount> kinds{TCFARM_SHAPE_KINDS(TCFARM_SHAPE_KIND_ENTRY)};
#undef TCFARM_SHAPE_KIND_ENTRY
  return *kinds[static_cast<size_t>(shape.type)];
}

BoundingSphere BoundsOf(const std::vector<Vec3>& points) {
  if (points.empty()) return {};
  Vec3 lo = points.front(), hi = points.front();
  for (const Vec3& p : points) {
    for (int i = 0; i < 3; ++i) {
      lo[i] = std::min(lo[i], p[i]);
      hi[i] = std::max(hi[i], p[i]);
    }
  }
  Vec3 c{(lo.x + hi.x) / 2, (lo.y + hi.y) / 2, (lo.z + hi.z) / 2};
  double r2 = 0;
  for (const Vec3& p : points) {
    r2 = std::max(r2, (p.x - c.x) * (p.x - c.x) + (p.y - c.y) * (p.y - c.y) + (p.z - c.z) * (p.z - c.z));
  }
  return {c, std::sqrt(r2)};
}

Float3 UnitNormal(const Vec3& a, const Vec3& b) {
  Vec3 n{a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
  double length = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
  return length > 0 ? ToFloat3({n.x / length, n.y / length, n.z / length}) : Float3{};
}

}  // namespace tcfarm
