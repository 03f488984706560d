// Test support: the same scene in other units or elsewhere, to check that tracing and
// horizons do not depend on the scale or the origin of the coordinates.
#pragma once

#include "proto/scene/scene.h"

namespace tcfarm::test {

inline AnimatedVec3 ScaleAnimated(const AnimatedVec3& a, double s) {
  switch (a.kind()) {
    case AnimatedVec3::Kind::kConstant: {
      Vec3 c = a.constant();
      return AnimatedVec3::Constant({c.x * s, c.y * s, c.z * s});
    }
    case AnimatedVec3::Kind::kPolynomial: {
      auto coefficients = a.coefficients();
      for (auto& axis : coefficients) {
        for (double& c : axis) c *= s;
      }
      return AnimatedVec3::Polynomial(coefficients);
    }
    case AnimatedVec3::Kind::kKeyframes: {
      auto keys = a.keys();
      for (auto& key : keys) key.value = {key.value.x * s, key.value.y * s, key.value.z * s};
      return AnimatedVec3::Keyframes(keys);
    }
  }
  return a;
}

inline Vec3 Scale(Vec3 v, double s) { return {v.x * s, v.y * s, v.z * s}; }

// The same world in other units: every length times s, point-light intensities times
// s^2 so that the inverse-square falloff lands on the same irradiance.
inline Scene ScaleScene(Scene scene, double s) {
  scene.camera.position = ScaleAnimated(scene.camera.position, s);
  scene.camera.lookAt = ScaleAnimated(scene.camera.lookAt, s);
  for (Light& light : scene.lights) {
    light.position = ScaleAnimated(light.position, s);
    if (light.HasPosition()) light.intensity = ScaleAnimated(light.intensity, s * s);
  }
  for (Shape& shape : scene.shapes) {
    shape.motion.translation = ScaleAnimated(shape.motion.translation, s);
    shape.motion.pivot = Scale(shape.motion.pivot, s);
    shape.center = Scale(shape.center, s);
    shape.radius *= s;
    shape.corner = Scale(shape.corner, s);
    shape.edgeU = Scale(shape.edgeU, s);
    shape.edgeV = Scale(shape.edgeV, s);
    for (Vec3& v : shape.mesh.vertices) v = Scale(v, s);
  }
  for (auto& [name, shared] : scene.meshes) {
    auto scaled = std::make_shared<TriangleMesh>(*shared);
    for (Vec3& v : scaled->vertices) v = Scale(v, s);
    shared = std::move(scaled);
  }
  for (Shape& shape : scene.shapes) {
    if (shape.SharesMesh()) shape.sharedMesh = scene.meshes.at(shape.meshRef);
  }
  return scene;
}

// The same world moved by `offset`.
inline Scene TranslatedScene(Scene scene, Vec3 offset) {
  TranslateScene(scene, offset);
  return scene;
}

}  // namespace tcfarm::test
