// A triangle mesh (inline, from OBJ, or a generated terrain): one Embree triangle geometry.
#include "shapes/shape_kind.h"

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
    std::vector<Float3> normals;
    normals.reserve(shape.Mesh().triangles.size());
    const auto& v = shape.Mesh().vertices;
    for (const auto& t : shape.Mesh().triangles) {
      normals.push_back(UnitNormal(Sub(v[t[1]], v[t[0]]), Sub(v[t[2]], v[t[0]])));
    }
    return normals;
  }
  std::vector<Float3> VertexNormals(const Shape& shape) const override {
    std::vector<Float3> normals;
    normals.reserve(shape.Mesh().normals.size());
    for (const Vec3& n : shape.Mesh().normals) {
      const double length = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
      normals.push_back(length > 0 ? ToFloat3({n.x / length, n.y / length, n.z / length}) : Float3{});
    }
    return normals;
  }
  BoundingSphere Bounds(const Shape& shape) const override { return BoundsOf(shape.Mesh().vertices); }
};

}  // namespace

const ShapeKind& TriangleMeshKind() {
  static const TriangleMeshShape kind;
  return kind;
}

}  // namespace tcfarm
