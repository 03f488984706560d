#include "trace/lights.h"

#include <limits>

namespace tcfarm {

bool ShadingLight::Toward(Float3 point, Float3 normal, Float3* direction, float* distance) const {
  if (isPoint) {
    Float3 toLight = position - point;
    *distance = Length(toLight);
    if (!(*distance > 0)) return false;
    *direction = toLight * (1.0f / *distance);
  } else {
    *direction = towardLight;
    *distance = std::numeric_limits<float>::infinity();
  }
  return Dot(*direction, normal) > 0;
}

std::vector<ShadingLight> MakeLights(const Scene& scene, int frame) {
  std::vector<ShadingLight> lights;
  for (const Light& light : scene.lights) {
    ShadingLight s{};
    s.isPoint = light.type == Light::Type::kPoint;
    s.intensity = ToFloat3(light.intensity.Evaluate(frame));
    if (s.isPoint) {
      s.position = ToFloat3(light.PositionAt(frame));
    } else {
      Vec3 d = NormalizeD(light.DirectionAt(frame));
      s.towardLight = ToFloat3({-d.x, -d.y, -d.z});
    }
    lights.push_back(s);
  }
  return lights;
}

}  // namespace tcfarm
