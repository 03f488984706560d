// What a worker needs of one kind of shape, behind one interface: the Embree geometry that
// traces it, its face normals for shading, and its bounds for the horizons of `exact`.
// One file per kind (sphere.cpp, quad.cpp, triangle_mesh.cpp), each defining the
// <Stem>Kind() that TCFARM_SHAPE_KINDS (scene.h) names; the tracer, the frame geometry,
// the horizon oracle and the tie test take a new kind as it is.
#pragma once

#include <embree3/rtcore.h>

#include <functional>
#include <map>
#include <memory>
#include <vector>

#include "proto/scene/scene.h"
#include "worker/trace/float3.h"

namespace tcfarm {

struct BoundingSphere {
  Vec3 center;
  double radius = 0;
};

// The bounding sphere of a point set: the centre of their box, the farthest point's distance.
BoundingSphere BoundsOf(const std::vector<Vec3>& points);

// The unit normal of the plane spanned by a and b, computed in double; zero when they
// span none.
Float3 UnitNormal(const Vec3& a, const Vec3& b);

// A shape's normals as the tracer shades with them. faces: per primitive, the unit face
// normal computed in double from the scene (Embree's robust intersector derives Ng from
// ray-relative vertices, so its last bits change with the ray origin, while a still
// surface must shade to the same bits from any viewpoint); empty for spheres, whose
// normal comes from the hit point. vertices: the unit shading normals a smooth mesh
// interpolates (zero where the scene gives none); empty for flat shapes.
struct SurfaceNormals {
  std::vector<Float3> faces;
  std::vector<Float3> vertices;
};

// Per shape, a table `make(shape)` computes from what it places (normals, texture
// coordinates: in object space), once per shared mesh: its placements share one.
template <typename Value, typename Make>
std::vector<std::shared_ptr<const Value>> PerShapeOncePerMesh(const std::vector<Shape>& shapes, Make make) {
  std::vector<std::shared_ptr<const Value>> tables;
  std::map<const TriangleMesh*, size_t> firstShapeOfMesh;
  for (const Shape& shape : shapes) {
    if (shape.SharesMesh()) {
      auto [first, isNew] = firstShapeOfMesh.emplace(shape.sharedMesh.get(), tables.size());
      if (!isNew) {
        tables.push_back(tables[first->second]);
        continue;
      }
    }
    tables.push_back(std::make_shared<const Value>(make(shape)));
  }
  return tables;
}

// Per triangle over `vertices`, its unit normal (UnitNormal of its edges).
std::vector<Float3> TriangleFaceNormals(const std::vector<Vec3>& vertices,
                                        const std::vector<std::array<uint32_t, 3>>& triangles);
// Each normal at unit length, in float; zero stays zero.
std::vector<Float3> UnitVertexNormals(const std::vector<Vec3>& normals);

class ShapeKind {
 public:
  virtual ~ShapeKind() = default;
  // An uncommitted Embree geometry of the shape in its rest pose (the caller places it).
  virtual RTCGeometry NewGeometry(RTCDevice device, const Shape& shape) const = 0;
  // Per primitive, in Embree's primitive order: the unit face normal, computed in double
  // from the scene. Embree's robust intersector derives its Ng from ray-relative vertices,
  // so its last bits change with the ray's origin, while a still surface must shade to the
  // same bits from any viewpoint. Empty when the normal comes from the hit (a sphere's).
  virtual std::vector<Float3> FaceNormals(const Shape& shape) const = 0;
  // Per vertex, in the geometry's vertex order: unit shading normals computed in double
  // (zero where the scene gives none or a zero one). Empty when the shape shades flat.
  virtual std::vector<Float3> VertexNormals(const Shape&) const { return {}; }
  // Bounds of the shape in its rest pose.
  virtual BoundingSphere Bounds(const Shape& shape) const = 0;
  // Whether its primitives share edges (a mesh's triangles, a quad's two halves), through
  // which a ray may slip unless Embree traverses robustly (scene_geometry.h).
  virtual bool SharesEdges() const { return true; }
  // Whether every primitive is flat (a quad, a triangle): flat primitives of two shapes
  // may lie in one plane, where which is hit is a tie (tie_candidates.h). Every kind says,
  // so that no curved one is taken for flat, nor the other way round.
  virtual bool Planar() const = 0;
  // Three points spanning each flat primitive, not in a line, in its rest pose, in
  // Embree's primitive order. Nothing for a kind that is not planar.
  using FaceVisitor = std::function<void(const Vec3&, const Vec3&, const Vec3&)>;
  virtual void ForEachFace(const Shape&, const FaceVisitor&) const {}
};

#define TCFARM_DECLARE_SHAPE_KIND(Stem) const ShapeKind& Stem##Kind();
TCFARM_SHAPE_KINDS(TCFARM_DECLARE_SHAPE_KIND)
#undef TCFARM_DECLARE_SHAPE_KIND

const ShapeKind& KindOf(const Shape& shape);

}  // namespace tcfarm
