// Lights as the shading of one frame sees them: one struct per kind of light, each the one
// place that says where its light comes from and how much of it arrives. TCFARM_LIGHT_KINDS
// (scene.h) names them: X(Stem) is the struct <Stem>Shading here, made from the scene's
// light at a frame, with
//   bool Toward(point, normal, &direction, &distance): the unit direction and distance from
//     `point` to the light (infinity for a light from afar); false when it adds nothing
//     there (behind the surface of unit `normal`, at the point itself, outside a spot's
//     cone, beyond its range): then no shadow ray is needed;
//   float Arriving(direction, distance): the share of its intensity that arrives along what
//     Toward gave (falloff with distance, cone);
//   const Float3* Position(): where it is, for the fans of the horizons; null from afar;
//   Vec3 WayFrom(p): in double, the way from p to the light (to its position, or its unit
//     direction from afar), for the horizons' sure tests.
// All are inline and the kinds a std::variant: asked for every hit and light, calls would
// cost more than the work.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <variant>
#include <vector>

#include "proto/scene/scene.h"
#include "worker/trace/float3.h"

namespace tcfarm {

// How a point or spot light falls with distance: with the square of it, and with a range
// (glTF's KHR_lights_punctual) smoothly to nothing at the range.
struct DistanceFalloff {
  float range;  // 0: no range, the pure inverse square

  // glTF's clamp(1 - (d / range)^4, 0, 1): the share a range lets reach `distance`.
  float RangeShare(float distance) const {
    const float ratio = distance / range;
    const float ratio2 = ratio * ratio;
    return std::clamp(1.0f - ratio2 * ratio2, 0.0f, 1.0f);
  }
  // Whether any of the light reaches `distance`; false where the range ends it.
  bool Reaches(float distance) const { return !(range > 0) || RangeShare(distance) > 0; }
  float operator()(float distance) const {
    if (range > 0) return RangeShare(distance) / (distance * distance);
    return 1.0f / (distance * distance);
  }
};

// The unit direction and distance from `point` to `position`; false where they meet.
inline bool TowardPosition(Float3 position, Float3 point, Float3* direction, float* distance) {
  const Float3 toLight = position - point;
  *distance = Length(toLight);
  if (!(*distance > 0)) return false;
  *direction = toLight * (1.0f / *distance);
  return true;
}

inline Vec3 ToVec3(Float3 v) { return {v.x, v.y, v.z}; }

// Shining every way from its position, falling off with distance.
struct PointShading {
  Float3 position;
  DistanceFalloff falloff;

  PointShading(const Light& light, int frame)
      : position(ToFloat3(light.PositionAt(frame))), falloff{static_cast<float>(light.range)} {}
  bool Toward(Float3 point, Float3 normal, Float3* direction, float* distance) const {
    return TowardPosition(position, point, direction, distance) && Dot(*direction, normal) > 0 &&
           falloff.Reaches(*distance);
  }
  float Arriving(Float3, float distance) const { return falloff(distance); }
  const Float3* Position() const { return &position; }
  Vec3 WayFrom(const Vec3& p) const { return SubtractD(ToVec3(position), p); }
};

// Arriving along one direction everywhere, undiminished (the sun).
struct DirectionalShading {
  Float3 towardLight;  // unit vector from any surface to the light

  DirectionalShading(const Light& light, int frame) {
    const Vec3 d = NormalizeD(light.DirectionAt(frame));
    towardLight = ToFloat3({-d.x, -d.y, -d.z});
  }
  bool Toward(Float3, Float3 normal, Float3* direction, float* distance) const {
    *direction = towardLight;
    *distance = std::numeric_limits<float>::infinity();
    return Dot(*direction, normal) > 0;
  }
  float Arriving(Float3, float) const { return 1.0f; }
  const Float3* Position() const { return nullptr; }
  Vec3 WayFrom(const Vec3&) const { return ToVec3(towardLight); }
};

// A point light within a cone about its axis: glTF's share = saturate(cos * scale +
// offset)^2, 1 inside the inner cone, 0 outside the outer one.
struct SpotShading {
  Float3 position;
  DistanceFalloff falloff;
  Float3 axis;  // unit direction the light travels
  float coneScale, coneOffset;

  SpotShading(const Light& light, int frame)
      : position(ToFloat3(light.PositionAt(frame))),
        falloff{static_cast<float>(light.range)},
        axis(ToFloat3(NormalizeD(light.DirectionAt(frame)))) {
    // The scale is bounded so that equal cones do not divide by zero.
    const double cosOuter = std::cos(light.outerConeDegrees * M_PI / 180);
    const double cosInner = std::cos(light.innerConeDegrees * M_PI / 180);
    const double scale = 1 / std::max(0.001, cosInner - cosOuter);
    coneScale = static_cast<float>(scale);
    coneOffset = static_cast<float>(-cosOuter * scale);
  }
  // The share of its intensity the cone sends toward the surface `towardLight` leads from.
  float Cone(Float3 towardLight) const {
    float share = std::clamp(-Dot(towardLight, axis) * coneScale + coneOffset, 0.0f, 1.0f);
    return share * share;
  }
  bool Toward(Float3 point, Float3 normal, Float3* direction, float* distance) const {
    return TowardPosition(position, point, direction, distance) && Dot(*direction, normal) > 0 &&
           falloff.Reaches(*distance) && Cone(*direction) > 0;
  }
  float Arriving(Float3 towardLight, float distance) const { return falloff(distance) * Cone(towardLight); }
  const Float3* Position() const { return &position; }
  Vec3 WayFrom(const Vec3& p) const { return SubtractD(ToVec3(position), p); }
};

// A std::variant of the kinds in Light::Type's order (the first, ignored argument takes
// the list's leading comma).
template <typename Ignored, typename... Kinds>
using VariantOfKinds = std::variant<Kinds...>;
#define TCFARM_LIGHT_SHADING(Stem) , Stem##Shading
using AnyLightShading = VariantOfKinds<void TCFARM_LIGHT_KINDS(TCFARM_LIGHT_SHADING)>;
#undef TCFARM_LIGHT_SHADING

// One light of one frame: its intensity, and its kind's shading.
struct ShadingLight {
  Float3 intensity;  // linear RGB radiant intensity, or irradiance from afar
  AnyLightShading kind;

  bool Toward(Float3 point, Float3 normal, Float3* direction, float* distance) const {
    return std::visit([&](const auto& k) { return k.Toward(point, normal, direction, distance); }, kind);
  }
  float Arriving(Float3 towardLight, float distance) const {
    return std::visit([&](const auto& k) { return k.Arriving(towardLight, distance); }, kind);
  }
  const Float3* Position() const {
    return std::visit([](const auto& k) { return k.Position(); }, kind);
  }
  Vec3 WayFrom(const Vec3& p) const {
    return std::visit([&](const auto& k) { return k.WayFrom(p); }, kind);
  }
};

std::vector<ShadingLight> MakeLights(const Scene& scene, int frame);

}  // namespace tcfarm
