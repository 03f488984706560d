#include "embree/tie_candidates.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <unordered_set>
#include <vector>

namespace tcfarm {
namespace {

// Planes and radii are compared on a grid this fine, relative to the scene's size: far
// coarser than float rounding (~6e-8), so surfaces that float cannot tell apart always
// fall together, fine enough that surfaces meant to be apart stay apart.
constexpr double kRelativeGrid = 1e-5;
// Past this many triangles a mesh carries the tie rule without its planes being hashed:
// the hash would cost more memory than the rule costs time.
constexpr size_t kMaxHashedTriangles = 2'000'000;

bool IsPlanar(const Shape& shape) { return shape.type != Shape::Type::kSphere; }

struct Plane {
  Vec3 normal;  // unit
  double offset;
};

bool PlaneOf(const Vec3& a, const Vec3& b, const Vec3& c, Plane* plane) {
  const Vec3 u{b.x - a.x, b.y - a.y, b.z - a.z}, v{c.x - a.x, c.y - a.y, c.z - a.z};
  Vec3 n{u.y * v.z - u.z * v.y, u.z * v.x - u.x * v.z, u.x * v.y - u.y * v.x};
  const double length = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
  if (!(length > 0)) return false;  // no area, no tie over one
  n = {n.x / length, n.y / length, n.z / length};
  *plane = {n, n.x * a.x + n.y * a.y + n.z * a.z};
  return true;
}

// The planes of a still planar shape's primitives, where its constant transform puts them.
template <typename Visit>
void ForEachPlane(const Shape& shape, int firstFrame, Visit visit) {
  const Affine placement = shape.motion.WorldFromObject(firstFrame);
  Plane plane;
  if (shape.type == Shape::Type::kQuad) {
    const Vec3& c = shape.corner;
    const Vec3 u{c.x + shape.edgeU.x, c.y + shape.edgeU.y, c.z + shape.edgeU.z};
    const Vec3 v{c.x + shape.edgeV.x, c.y + shape.edgeV.y, c.z + shape.edgeV.z};
    if (PlaneOf(placement.Apply(c), placement.Apply(u), placement.Apply(v), &plane)) visit(plane);
    return;
  }
  const auto& vertices = shape.Mesh().vertices;
  for (const auto& t : shape.Mesh().triangles) {
    if (PlaneOf(placement.Apply(vertices[t[0]]), placement.Apply(vertices[t[1]]),
                placement.Apply(vertices[t[2]]), &plane)) {
      visit(plane);
    }
  }
}

using PlaneKey = std::array<int64_t, 4>;

struct PlaneKeyHash {
  size_t operator()(const PlaneKey& key) const {
    uint64_t h = 1469598103934665603ull;
    for (int64_t part : key) h = (h ^ static_cast<uint64_t>(part)) * 1099511628211ull;
    return static_cast<size_t>(h);
  }
};

PlaneKey KeyOf(const Plane& plane, double size) {
  auto cell = [](double value, double grid) { return static_cast<int64_t>(std::llround(value / grid)); };
  return {cell(plane.normal.x, kRelativeGrid), cell(plane.normal.y, kRelativeGrid),
          cell(plane.normal.z, kRelativeGrid), cell(plane.offset, kRelativeGrid * size)};
}

// Whether two still planar primitives (of one shape or two) lie in one plane, either way
// round (a face seen from behind coincides as well). Planes are computed once, then their
// offsets compared on a grid scaled to the largest of them.
bool StillPlanesCoincide(const Scene& scene) {
  std::vector<Plane> planes;
  for (const Shape& shape : scene.shapes) {
    if (!IsPlanar(shape) || shape.Moves()) continue;
    if (shape.Mesh().triangles.size() > kMaxHashedTriangles) return true;
    ForEachPlane(shape, scene.render.firstFrame, [&](const Plane& plane) { planes.push_back(plane); });
  }
  double size = 1;
  for (const Plane& plane : planes) size = std::max(size, std::fabs(plane.offset));
  std::unordered_set<PlaneKey, PlaneKeyHash> seen;
  for (const Plane& plane : planes) {
    const Plane flipped{{-plane.normal.x, -plane.normal.y, -plane.normal.z}, -plane.offset};
    if (!seen.insert(KeyOf(plane, size)).second || !seen.insert(KeyOf(flipped, size)).second) return true;
  }
  return false;
}

// Whether two spheres may coincide: equal radii where one moves or both share a centre,
// or any at all once a sphere scales.
bool SpheresMayMeet(const Scene& scene) {
  std::vector<const Shape*> spheres;
  bool anyScales = false;
  for (const Shape& shape : scene.shapes) {
    if (shape.type != Shape::Type::kSphere) continue;
    spheres.push_back(&shape);
    anyScales = anyScales || !shape.motion.IsTranslationOnly();
  }
  if (spheres.size() < 2) return false;
  if (anyScales) return true;
  auto near = [](double a, double b) {
    return std::fabs(a - b) <= kRelativeGrid * std::max({1.0, std::fabs(a), std::fabs(b)});
  };
  for (size_t a = 0; a < spheres.size(); ++a) {
    for (size_t b = a + 1; b < spheres.size(); ++b) {
      const Shape& s = *spheres[a];
      const Shape& t = *spheres[b];
      const Vec3 sc = s.motion.WorldFromObject(scene.render.firstFrame).Apply(s.center);
      const Vec3 tc = t.motion.WorldFromObject(scene.render.firstFrame).Apply(t.center);
      const bool sameCentre = near(sc.x, tc.x) && near(sc.y, tc.y) && near(sc.z, tc.z);
      if (near(s.radius, t.radius) && (s.Moves() || t.Moves() || sameCentre)) return true;
    }
  }
  return false;
}

}  // namespace

bool SceneMayTie(const Scene& scene) {
  // A moving plane may come to lie in any other at some frame.
  const bool planarMoves = std::any_of(scene.shapes.begin(), scene.shapes.end(),
                                       [](const Shape& shape) { return IsPlanar(shape) && shape.Moves(); });
  return planarMoves || StillPlanesCoincide(scene) || SpheresMayMeet(scene);
}

}  // namespace tcfarm
