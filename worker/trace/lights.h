// Point and directional lights as the shading of one frame sees them.
#pragma once

#include <vector>

#include "scene/scene.h"
#include "trace/float3.h"

namespace tcfarm {

struct ShadingLight {
  bool isPoint;
  Float3 position;     // point lights
  Float3 towardLight;  // directional lights: unit vector from the surface to the light
  Float3 intensity;

  // The unit direction and distance from `point` to the light (infinity for a directional
  // one). False when the light is behind the surface of unit `normal`, or at the point
  // itself: then it adds nothing and no shadow ray is needed.
  bool Toward(Float3 point, Float3 normal, Float3* direction, float* distance) const;
  // Inverse-square falloff of a point light; none for a directional one.
  float Falloff(float distance) const { return isPoint ? 1.0f / (distance * distance) : 1.0f; }
};

std::vector<ShadingLight> MakeLights(const Scene& scene, int frame);

}  // namespace tcfarm
