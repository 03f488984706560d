#include "worker/trace/lights.h"

namespace tcfarm {
namespace {

ShadingLight MakeLight(const Light& light, int frame) {
  const Float3 intensity = ToFloat3(light.intensity.Evaluate(frame));
  switch (light.type) {
#define TCFARM_MAKE_LIGHT_SHADING(Stem) \
  case Light::Type::k##Stem:            \
    return {intensity, Stem##Shading(light, frame)};
    TCFARM_LIGHT_KINDS(TCFARM_MAKE_LIGHT_SHADING)
#undef TCFARM_MAKE_LIGHT_SHADING
  }
  return {intensity, PointShading(light, frame)};  // no such type: the switch covers each
}

}  // namespace

std::vector<ShadingLight> MakeLights(const Scene& scene, int frame) {
  std::vector<ShadingLight> lights;
  for (const Light& light : scene.lights) lights.push_back(MakeLight(light, frame));
  return lights;
}

}  // namespace tcfarm
