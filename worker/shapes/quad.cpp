// A parallelogram: corner, corner + u, corner + u + v, corner + v; one Embree quad.
#include "worker/shapes/shape_kind.h"

namespace tcfarm {
namespace {

Vec3 Add(const Vec3& a, const Vec3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }

std::vector<Vec3> Corners(const Shape& shape) {
  const Vec3& c = shape.corner;
  return {c, Add(c, shape.edgeU), Add(Add(c, shape.edgeU), shape.edgeV), Add(c, shape.edgeV)};
}

class QuadShape final : public ShapeKind {
 public:
  RTCGeometry NewGeometry(RTCDevice device, const Shape& shape) const override {
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_QUAD);
    const std::vector<Vec3> corners = Corners(shape);
    auto* vertex = static_cast<float*>(rtcSetNewGeometryBuffer(
        geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), corners.size()));
    for (size_t i = 0; i < corners.size(); ++i) {
      for (int axis = 0; axis < 3; ++axis) vertex[3 * i + axis] = static_cast<float>(corners[i][axis]);
    }
    auto* index = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
        geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT4, 4 * sizeof(unsigned), 1));
    for (unsigned i = 0; i < 4; ++i) index[i] = i;
    return geometry;
  }
  std::vector<Float3> FaceNormals(const Shape& shape) const override {
    return {UnitNormal(shape.edgeU, shape.edgeV)};
  }
  BoundingSphere Bounds(const Shape& shape) const override { return BoundsOf(Corners(shape)); }
  bool Planar() const override { return true; }
  // Its plane through the corner and the two edges' ends.
  void ForEachFace(const Shape& shape, const FaceVisitor& visit) const override {
    visit(shape.corner, Add(shape.corner, shape.edgeU), Add(shape.corner, shape.edgeV));
  }
};

}  // namespace

const ShapeKind& QuadKind() {
  static const QuadShape kind;
  return kind;
}

}  // namespace tcfarm
