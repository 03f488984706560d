// A sphere: Embree's sphere point primitive, shaded by the normal at the hit.
#include "worker/shapes/shape_kind.h"

namespace tcfarm {
namespace {

class SphereShape final : public ShapeKind {
 public:
  RTCGeometry NewGeometry(RTCDevice device, const Shape& shape) const override {
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_SPHERE_POINT);
    auto* point = static_cast<float*>(rtcSetNewGeometryBuffer(
        geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 4 * sizeof(float), 1));
    point[0] = static_cast<float>(shape.center.x);
    point[1] = static_cast<float>(shape.center.y);
    point[2] = static_cast<float>(shape.center.z);
    point[3] = static_cast<float>(shape.radius);
    return geometry;
  }
  std::vector<Float3> FaceNormals(const Shape&) const override { return {}; }
  BoundingSphere Bounds(const Shape& shape) const override { return {shape.center, shape.radius}; }
  bool SharesEdges() const override { return false; }
  bool Planar() const override { return false; }
};

}  // namespace

const ShapeKind& SphereKind() {
  static const SphereShape kind;
  return kind;
}

}  // namespace tcfarm
