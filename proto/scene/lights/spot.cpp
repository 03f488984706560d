// A spot light: {"type": "spot", "position", "direction", "intensity", "range",
// "inner_cone_degrees", "outer_cone_degrees"}, a point light shining within a cone about
// its direction (glTF's KHR_lights_punctual spot).
#include "proto/scene/lights/light_format.h"
#include "proto/scene/parse/scene_reader.h"
#include "proto/scene/scene_write.h"

namespace tcfarm {
namespace {

using namespace scene_parse;
using scene_write::AnimatedJson;

// glTF's bounds: 0 <= inner < outer <= 90 degrees.
void ReadCone(const Node& node, Light& light) {
  const std::string outerExpected = "an outer cone angle in (0, 90] degrees from the axis";
  if (node.Has("outer_cone_degrees")) {
    Node outer = node.Member("outer_cone_degrees");
    light.outerConeDegrees = ReadNumber(outer, outerExpected);
    if (!(light.outerConeDegrees > 0 && light.outerConeDegrees <= 90)) {
      Fail(outer.pointer, Show(outer.value) + " is out of range", outerExpected);
    }
  }
  if (node.Has("inner_cone_degrees")) {
    Node inner = node.Member("inner_cone_degrees");
    const std::string innerExpected = "an inner cone angle in [0, outer_cone_degrees) degrees";
    light.innerConeDegrees = ReadNumber(inner, innerExpected);
    if (!(light.innerConeDegrees >= 0 && light.innerConeDegrees < light.outerConeDegrees)) {
      Fail(inner.pointer, Show(inner.value) + " is not below the outer cone's " + FormatNumber(light.outerConeDegrees),
           innerExpected);
    }
  }
}

class SpotFormatImpl final : public LightFormat {
 public:
  const char* Name() const override { return "spot"; }
  bool HasPosition() const override { return true; }
  bool HasDirection() const override { return true; }

  void Read(SceneReader& reader, const Node& node, Light& light) const override {
    ExpectObject(node,
                 {"type", "position", "direction", "intensity", "range", "inner_cone_degrees", "outer_cone_degrees", "motion"},
                 "a spot light");
    light.position = reader.ReadLightPosition(node);
    light.direction = reader.ReadLightDirection(node);
    ReadCone(node, light);
  }

  json Write(const Light& light) const override {
    return json{{"position", AnimatedJson(light.position)},
                {"direction", AnimatedJson(light.direction)},
                {"inner_cone_degrees", light.innerConeDegrees},
                {"outer_cone_degrees", light.outerConeDegrees}};
  }

  void Translate(Light& light, const Vec3& offset) const override {
    light.position = Offset(light.position, offset);
  }
};

}  // namespace

const LightFormat& SpotLightFormat() {
  static const SpotFormatImpl format;
  return format;
}

}  // namespace tcfarm
