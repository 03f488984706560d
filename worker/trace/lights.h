// Point and directional lights as the shading of one frame sees them.
#pragma once

#include <algorithm>
#include <limits>
#include <vector>

#include "proto/scene/scene.h"
#include "worker/trace/float3.h"

namespace tcfarm {

struct ShadingLight {
  bool isPoint;        // point and spot lights
  bool isSpot;
  Float3 position;     // point and spot lights
  Float3 towardLight;  // directional lights: unit vector from the surface to the light
  Float3 axis;         // spot lights: unit direction the light travels
  float coneScale, coneOffset;  // spot lights: cosine to cone factor, as glTF defines it
  Float3 intensity;

  // The unit direction and distance from `point` to the light (infinity for a directional
  // one). False when the light is behind the surface of unit `normal`, at the point itself,
  // or a spot whose cone leaves the point out: then it adds nothing and no shadow ray is
  // needed.
  // Inline, as Cone: asked for every hit and light, they cost more as calls than as work.
  bool Toward(Float3 point, Float3 normal, Float3* direction, float* distance) const {
    if (isPoint) {
      Float3 toLight = position - point;
      *distance = Length(toLight);
      if (!(*distance > 0)) return false;
      *direction = toLight * (1.0f / *distance);
    } else {
      *direction = towardLight;
      *distance = std::numeric_limits<float>::infinity();
    }
    return Dot(*direction, normal) > 0 && Cone(*direction) > 0;
  }
  // A spot light's share of its intensity arriving from `towardLight` (1 for the others).
  float Cone(Float3 towardLight) const {
    if (!isSpot) return 1.0f;
    float share = std::clamp(-Dot(towardLight, axis) * coneScale + coneOffset, 0.0f, 1.0f);
    return share * share;
  }
  // Inverse-square falloff of a point light; none for a directional one.
  float Falloff(float distance) const { return isPoint ? 1.0f / (distance * distance) : 1.0f; }
};

std::vector<ShadingLight> MakeLights(const Scene& scene, int frame);

}  // namespace tcfarm
