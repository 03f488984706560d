// A sphere: {"type": "sphere", "center", "radius"}.
#include <cmath>

#include "proto/scene/parse/scene_reader.h"
#include "proto/scene/scene_write.h"
#include "proto/scene/shapes/shape_format.h"

namespace tcfarm {
namespace {

using namespace scene_parse;
using scene_write::Vec3Json;

// Whether the linear part is a rotation times one scale factor (then a sphere stays a
// sphere): its columns orthogonal and of equal length.
bool IsUniform(const Affine& placement) {
  const auto& m = placement.linear;
  auto column = [&](int c) { return Vec3{m[0][c], m[1][c], m[2][c]}; };
  auto dot = [](const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; };
  const double lengthSquared = dot(column(0), column(0));
  const double tolerance = 1e-12 * lengthSquared;
  return std::fabs(dot(column(1), column(1)) - lengthSquared) <= tolerance &&
         std::fabs(dot(column(2), column(2)) - lengthSquared) <= tolerance &&
         std::fabs(dot(column(0), column(1))) <= tolerance && std::fabs(dot(column(0), column(2))) <= tolerance &&
         std::fabs(dot(column(1), column(2))) <= tolerance;
}

class SphereFormatImpl final : public ShapeFormat {
 public:
  const char* Name() const override { return "sphere"; }

  void Read(SceneReader&, const Node& node, Shape& shape) const override {
    ExpectObject(node, SceneReader::ShapeFields({"center", "radius"}), "a sphere");
    shape.center = ReadVec3(Required(node, "center", kVec3Expected));
    shape.radius = ReadPositive(Required(node, "radius", "a positive finite number"), "a positive finite number");
  }

  json Write(const Shape& shape) const override {
    return json{{"center", Vec3Json(shape.center)}, {"radius", shape.radius}};
  }

  void Translate(Shape& shape, const Vec3& offset) const override { shape.center = Moved(shape.center, offset); }

  bool PlaceStill(Shape& shape, const Affine& placement) const override {
    if (!IsUniform(placement)) return false;
    shape.center = placement.Apply(shape.center);
    shape.radius *= placement.MaxStretch();
    return true;
  }
};

}  // namespace

const ShapeFormat& SphereFormat() {
  static const SphereFormatImpl format;
  return format;
}

}  // namespace tcfarm
