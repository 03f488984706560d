#include "worker/embree/tie_candidates.h"

#include "worker/shapes/shape_kind.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <iterator>
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

bool IsPlanar(const Shape& shape) { return KindOf(shape).Planar(); }

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
  KindOf(shape).ForEachFace(shape, [&](const Vec3& a, const Vec3& b, const Vec3& c) {
    Plane plane;
    if (PlaneOf(placement.Apply(a), placement.Apply(b), placement.Apply(c), &plane)) visit(plane);
  });
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

// Two values equal within the comparison grid, relative to their size.
bool Near(double a, double b) {
  return std::fabs(a - b) <= kRelativeGrid * std::max({1.0, std::fabs(a), std::fabs(b)});
}

// Wider than Near by a margin: where a <= c <= d <= b and Near(a, b), every c, d between
// are LooselyNear (each is at least half the size of the larger of a, b). So a sweep over
// sorted values that stops where LooselyNear fails never stops between two Near values.
bool LooselyNear(double a, double b) {
  return std::fabs(a - b) <= 4 * kRelativeGrid * std::max({1.0, std::fabs(a), std::fabs(b)});
}

// A sphere as the meeting test sees it: radius and centre at the first frame.
struct SphereKey {
  std::array<double, 4> value;  // radius, x, y, z
  bool moves;
};

bool SameRadius(const SphereKey& a, const SphereKey& b) { return Near(a.value[0], b.value[0]); }
bool SameSphere(const SphereKey& a, const SphereKey& b) {
  for (size_t i = 0; i < a.value.size(); ++i) {
    if (!Near(a.value[i], b.value[i])) return false;
  }
  return true;
}

// Whether any sphere that moves has another of its radius. Sorted by radius, the spheres
// of a moving one's radius lie beside it; the sweep goes only as far as radii stay
// loosely near, so it looks at a handful of neighbours, not at every sphere.
bool MoverHasTwin(std::vector<SphereKey> spheres) {
  std::sort(spheres.begin(), spheres.end(), [](const SphereKey& a, const SphereKey& b) { return a.value[0] < b.value[0]; });
  for (size_t i = 0; i < spheres.size(); ++i) {
    if (!spheres[i].moves) continue;
    for (size_t j = i + 1; j < spheres.size() && LooselyNear(spheres[i].value[0], spheres[j].value[0]); ++j) {
      if (SameRadius(spheres[i], spheres[j])) return true;
    }
    for (size_t j = i; j-- > 0 && LooselyNear(spheres[i].value[0], spheres[j].value[0]);) {
      if (SameRadius(spheres[i], spheres[j])) return true;
    }
  }
  return false;
}

// Whether two of spheres[begin, end) coincide (radius and centre Near). Sort and sweep,
// one coordinate after another: sorted on `axis`, the spheres split into runs of loosely
// near values, and two coinciding spheres always share a run; each run is split again on
// the next coordinate. What is left after the last coordinate are spheres in (nearly) one
// place, compared pairwise: in any real scene those runs hold one or two spheres.
bool AnyCoincide(std::vector<SphereKey>& spheres, size_t begin, size_t end, size_t axis) {
  if (end - begin < 2) return false;
  if (axis == 4) {
    for (size_t a = begin; a < end; ++a) {
      for (size_t b = a + 1; b < end; ++b) {
        if (SameSphere(spheres[a], spheres[b])) return true;
      }
    }
    return false;
  }
  std::sort(spheres.begin() + static_cast<std::ptrdiff_t>(begin), spheres.begin() + static_cast<std::ptrdiff_t>(end),
            [axis](const SphereKey& a, const SphereKey& b) { return a.value[axis] < b.value[axis]; });
  size_t run = begin;
  for (size_t i = begin + 1; i <= end; ++i) {
    if (i < end && LooselyNear(spheres[i - 1].value[axis], spheres[i].value[axis])) continue;
    if (AnyCoincide(spheres, run, i, axis + 1)) return true;
    run = i;
  }
  return false;
}

}  // namespace

// Whether two spheres may coincide: equal radii where one moves or both share a centre,
// or any at all once a sphere scales.
bool SpheresMayMeet(const Scene& scene) {
  std::vector<SphereKey> spheres;
  bool anyScales = false;
  for (const Shape& shape : scene.shapes) {
    if (shape.type != Shape::Type::kSphere) continue;
    const Vec3 c = shape.motion.WorldFromObject(scene.render.firstFrame).Apply(shape.center);
    spheres.push_back({{shape.radius, c.x, c.y, c.z}, shape.Moves()});
    anyScales = anyScales || !shape.motion.IsTranslationOnly();
  }
  if (spheres.size() < 2) return false;
  if (anyScales) return true;
  if (MoverHasTwin(spheres)) return true;
  std::vector<SphereKey> still;
  std::copy_if(spheres.begin(), spheres.end(), std::back_inserter(still), [](const SphereKey& s) { return !s.moves; });
  return AnyCoincide(still, 0, still.size(), 0);
}

bool SceneMayTie(const Scene& scene) {
  // A moving plane may come to lie in any other at some frame.
  const bool planarMoves = std::any_of(scene.shapes.begin(), scene.shapes.end(),
                                       [](const Shape& shape) { return IsPlanar(shape) && shape.Moves(); });
  return planarMoves || StillPlanesCoincide(scene) || SpheresMayMeet(scene);
}

}  // namespace tcfarm
