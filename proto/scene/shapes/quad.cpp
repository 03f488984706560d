// A parallelogram: {"type": "quad", "corner", "edge_u", "edge_v"}, its corners corner,
// corner + edge_u, corner + edge_u + edge_v, corner + edge_v.
#include "proto/scene/parse/scene_reader.h"
#include "proto/scene/scene_write.h"
#include "proto/scene/shapes/shape_format.h"

namespace tcfarm {
namespace {

using namespace scene_parse;
using scene_write::Vec3Json;

class QuadFormatImpl final : public ShapeFormat {
 public:
  const char* Name() const override { return "quad"; }

  void Read(SceneReader&, const Node& node, Shape& shape) const override {
    ExpectObject(node, SceneReader::ShapeFields({"corner", "edge_u", "edge_v"}), "a quad");
    shape.corner = ReadVec3(Required(node, "corner", kVec3Expected));
    shape.edgeU = ReadVec3(Required(node, "edge_u", kVec3Expected));
    shape.edgeV = ReadVec3(Required(node, "edge_v", kVec3Expected));
    if (IsDegenerate(shape.edgeU, shape.edgeV)) {
      Fail(node.pointer, "edge_u x edge_v is zero: the quad has no area",
           "edge_u and edge_v non-zero and not parallel");
    }
  }

  json Write(const Shape& shape) const override {
    return json{{"corner", Vec3Json(shape.corner)}, {"edge_u", Vec3Json(shape.edgeU)}, {"edge_v", Vec3Json(shape.edgeV)}};
  }

  void Translate(Shape& shape, const Vec3& offset) const override { shape.corner = Moved(shape.corner, offset); }

  bool PlaceStill(Shape& shape, const Affine& placement) const override {
    shape.corner = placement.Apply(shape.corner);
    shape.edgeU = placement.ApplyLinear(shape.edgeU);
    shape.edgeV = placement.ApplyLinear(shape.edgeV);
    return true;
  }
};

}  // namespace

const ShapeFormat& QuadFormat() {
  static const QuadFormatImpl format;
  return format;
}

}  // namespace tcfarm
