#include "worker/trace/lights.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace tcfarm {

std::vector<ShadingLight> MakeLights(const Scene& scene, int frame) {
  std::vector<ShadingLight> lights;
  for (const Light& light : scene.lights) {
    ShadingLight s{};
    s.isPoint = light.HasPosition();
    s.isSpot = light.type == Light::Type::kSpot;
    s.intensity = ToFloat3(light.intensity.Evaluate(frame));
    if (s.isPoint) s.position = ToFloat3(light.PositionAt(frame));
    if (light.HasDirection()) {
      Vec3 d = NormalizeD(light.DirectionAt(frame));
      s.towardLight = ToFloat3({-d.x, -d.y, -d.z});
      s.axis = ToFloat3(d);
    }
    if (s.isSpot) {
      // glTF: share = saturate(cos * scale + offset)^2, 1 inside the inner cone, 0 outside
      // the outer one; the scale is bounded so equal cones do not divide by zero.
      const double cosOuter = std::cos(light.outerConeDegrees * M_PI / 180);
      const double cosInner = std::cos(light.innerConeDegrees * M_PI / 180);
      const double scale = 1 / std::max(0.001, cosInner - cosOuter);
      s.coneScale = static_cast<float>(scale);
      s.coneOffset = static_cast<float>(-cosOuter * scale);
    }
    lights.push_back(s);
  }
  return lights;
}

}  // namespace tcfarm
