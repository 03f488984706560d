// A triangle mesh (inline, from OBJ, or a generated terrain): one Embree triangle geometry.
#include "worker/shapes/shape_kind.h"

#include <cmath>
#include <cstring>

namespace tcfarm {
namespace {

Vec3 Sub(const Vec3& a, const Vec3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }

class TriangleMeshShape final : public ShapeKind {
 public:
  RTCGeometry NewGeometry(RTCDevice device, const Shape& shape) const override {
    const auto& mesh = shape.Mesh();
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* vertex = static_cast<float*>(rtcSetNewGeometryBuffer(
        geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), mesh.vertices.size()));
    for (size_t i = 0; i < mesh.vertices.size(); ++i) {
      for (int axis = 0; axis < 3; ++axis) vertex[3 * i + axis] = static_cast<float>(mesh.vertices[i][axis]);
    }
    auto* index = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
        geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), mesh.triangles.size()));
    std::memcpy(index, mesh.triangles.data(), mesh.triangles.size() * 3 * sizeof(unsigned));
    return geometry;
  }
  std::vector<Float3> FaceNormals(const Shape& shape) const override {
    return TriangleFaceNormals(shape.Mesh().vertices, shape.Mesh().triangles);
  }
  std::vector<Float3> VertexNormals(const Shape& shape) const override {
    return UnitVertexNormals(shape.Mesh().normals);
  }
  BoundingSphere Bounds(const Shape& shape) const override { return BoundsOf(shape.Mesh().vertices); }
  bool Planar() const override { return true; }
  void ForEachFace(const Shape& shape, const FaceVisitor& visit) const override {
    const auto& vertices = shape.Mesh().vertices;
    for (const auto& t : shape.Mesh().triangles) visit(vertices[t[0]], vertices[t[1]], vertices[t[2]]);
  }
};

}  // namespace

std::vector<Float3> TriangleFaceNormals(const std::vector<Vec3>& vertices,
                                        const std::vector<std::array<uint32_t, 3>>& triangles) {
  std::vector<Float3> normals;
  normals.reserve(triangles.size());
  for (const auto& t : triangles) {
    normals.push_back(UnitNormal(Sub(vertices[t[1]], vertices[t[0]]), Sub(vertices[t[2]], vertices[t[0]])));
  }
  return normals;
}

std::vector<Float3> UnitVertexNormals(const std::vector<Vec3>& normals) {
  std::vector<Float3> unit;
  unit.reserve(normals.size());
  for (const Vec3& n : normals) {
    const double length = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
    unit.push_back(length > 0 ? ToFloat3({n.x / length, n.y / length, n.z / length}) : Float3{});
  }
  return unit;
}

const ShapeKind& MeshKind() {
  static const TriangleMeshShape kind;
  return kind;
}

// Terrain is generated as a mesh (proto/scene/shapes/terrain.cpp), and traced as one.
const ShapeKind& TerrainKind() { return MeshKind(); }

}  // namespace tcfarm
