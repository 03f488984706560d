// A point light: {"type": "point", "position", "intensity", "range"}, shining every way
// from its position.
#include "proto/scene/lights/light_format.h"
#include "proto/scene/parse/scene_reader.h"
#include "proto/scene/scene_write.h"

namespace tcfarm {
namespace {

using namespace scene_parse;
using scene_write::AnimatedJson;

class PointFormatImpl final : public LightFormat {
 public:
  const char* Name() const override { return "point"; }
  bool HasPosition() const override { return true; }
  bool HasDirection() const override { return false; }

  void Read(SceneReader& reader, const Node& node, Light& light) const override {
    ExpectObject(node, {"type", "position", "intensity", "range", "motion"}, "a point light");
    light.position = reader.ReadLightPosition(node);
  }

  json Write(const Light& light) const override { return json{{"position", AnimatedJson(light.position)}}; }

  void Translate(Light& light, const Vec3& offset) const override {
    light.position = Offset(light.position, offset);
  }
};

}  // namespace

const LightFormat& PointLightFormat() {
  static const PointFormatImpl format;
  return format;
}

}  // namespace tcfarm
