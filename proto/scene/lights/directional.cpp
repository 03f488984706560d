// A directional light: {"type": "directional", "direction", "intensity"}, arriving along
// one direction everywhere (the sun), from no place the world's moves could shift.
#include "proto/scene/lights/light_format.h"
#include "proto/scene/parse/scene_reader.h"
#include "proto/scene/scene_write.h"

namespace tcfarm {
namespace {

using namespace scene_parse;
using scene_write::AnimatedJson;

class DirectionalFormatImpl final : public LightFormat {
 public:
  const char* Name() const override { return "directional"; }
  bool HasPosition() const override { return false; }
  bool HasDirection() const override { return true; }

  void Read(SceneReader& reader, const Node& node, Light& light) const override {
    ExpectObject(node, {"type", "direction", "intensity", "motion"}, "a directional light");
    light.direction = reader.ReadLightDirection(node);
  }

  json Write(const Light& light) const override { return json{{"direction", AnimatedJson(light.direction)}}; }
};

}  // namespace

const LightFormat& DirectionalLightFormat() {
  static const DirectionalFormatImpl format;
  return format;
}

}  // namespace tcfarm
