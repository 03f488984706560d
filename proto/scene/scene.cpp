#include "scene/scene.h"

#include <algorithm>
#include <utility>

namespace tcfarm {

AnimatedVec3 AnimatedVec3::Constant(Vec3 value) {
  AnimatedVec3 result;
  result.kind_ = Kind::kConstant;
  result.constant_ = value;
  return result;
}

AnimatedVec3 AnimatedVec3::Polynomial(std::array<std::vector<double>, 3> coefficients) {
  AnimatedVec3 result;
  result.kind_ = Kind::kPolynomial;
  result.coefficients_ = std::move(coefficients);
  return result;
}

AnimatedVec3 AnimatedVec3::Keyframes(std::vector<Keyframe> keys) {
  AnimatedVec3 result;
  result.kind_ = Kind::kKeyframes;
  result.keys_ = std::move(keys);
  return result;
}

namespace {

double EvaluateHorner(const std::vector<double>& coefficients, double frame) {
  double value = 0;
  for (auto it = coefficients.rbegin(); it != coefficients.rend(); ++it) {
    value = value * frame + *it;
  }
  return value;
}

// a + (b - a) * t keeps a component that does not change between two keys exactly
// equal to the key, so a still pixel stays bit-identical while another axis moves.
double Lerp(double a, double b, double t) { return a + (b - a) * t; }

Vec3 InterpolateKeys(const std::vector<AnimatedVec3::Keyframe>& keys, double frame) {
  if (keys.empty()) return Vec3{};
  if (frame <= keys.front().frame) return keys.front().value;
  if (frame >= keys.back().frame) return keys.back().value;
  auto after = std::upper_bound(keys.begin(), keys.end(), frame,
                                [](double f, const AnimatedVec3::Keyframe& key) { return f < key.frame; });
  const auto& next = *after;
  const auto& previous = *(after - 1);
  // frame < next.frame here, so t < 1 and each key is reached only through t == 0.
  double t = (frame - previous.frame) / (next.frame - previous.frame);
  return Vec3{Lerp(previous.value.x, next.value.x, t), Lerp(previous.value.y, next.value.y, t),
              Lerp(previous.value.z, next.value.z, t)};
}

}  // namespace

Vec3 AnimatedVec3::Evaluate(double frame) const {
  switch (kind_) {
    case Kind::kConstant:
      return constant_;
    case Kind::kPolynomial:
      return Vec3{EvaluateHorner(coefficients_[0], frame), EvaluateHorner(coefficients_[1], frame),
                  EvaluateHorner(coefficients_[2], frame)};
    case Kind::kKeyframes:
      return InterpolateKeys(keys_, frame);
  }
  return constant_;
}

bool AnimatedVec3::IsAnimated() const {
  switch (kind_) {
    case Kind::kConstant:
      return false;
    case Kind::kPolynomial:
      for (const auto& axis : coefficients_) {
        for (size_t k = 1; k < axis.size(); ++k) {
          if (axis[k] != 0) return true;
        }
      }
      return false;
    case Kind::kKeyframes:
      for (const auto& key : keys_) {
        if (key.value != keys_.front().value) return true;
      }
      return false;
  }
  return false;
}

bool Scene::CameraMoves() const { return camera.position.IsAnimated() || camera.lookAt.IsAnimated(); }

bool Scene::AnyLightChanges() const {
  return std::any_of(lights.begin(), lights.end(), [](const Light& light) {
    return light.position.IsAnimated() || light.direction.IsAnimated() || light.intensity.IsAnimated();
  });
}

bool Scene::AnyShapeMoves() const {
  return std::any_of(shapes.begin(), shapes.end(), [](const Shape& shape) { return shape.Moves(); });
}

bool Scene::AnyMaterialReflects() const {
  return std::any_of(materials.begin(), materials.end(),
                     [](const Material& material) { return material.Reflects(); });
}

bool Scene::AnyMaterialRefracts() const {
  return std::any_of(materials.begin(), materials.end(),
                     [](const Material& material) { return material.Refracts(); });
}

SceneError::SceneError(std::string pointer, const std::string& message)
    : std::runtime_error("scene" + pointer + ": " + message), pointer_(std::move(pointer)) {}

namespace {

Vec3 Plus(const Vec3& a, const Vec3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }

AnimatedVec3 Offset(const AnimatedVec3& value, const Vec3& offset) {
  switch (value.kind()) {
    case AnimatedVec3::Kind::kConstant:
      return AnimatedVec3::Constant(Plus(value.constant(), offset));
    case AnimatedVec3::Kind::kPolynomial: {
      auto coefficients = value.coefficients();
      coefficients[0][0] += offset.x;
      coefficients[1][0] += offset.y;
      coefficients[2][0] += offset.z;
      return AnimatedVec3::Polynomial(coefficients);
    }
    case AnimatedVec3::Kind::kKeyframes: {
      auto keys = value.keys();
      for (auto& key : keys) key.value = Plus(key.value, offset);
      return AnimatedVec3::Keyframes(keys);
    }
  }
  return value;
}

}  // namespace

void TranslateScene(Scene& scene, const Vec3& offset) {
  scene.camera.position = Offset(scene.camera.position, offset);
  scene.camera.lookAt = Offset(scene.camera.lookAt, offset);
  for (Light& light : scene.lights) {
    if (light.type == Light::Type::kPoint) light.position = Offset(light.position, offset);
  }
  for (Shape& shape : scene.shapes) {
    shape.center = Plus(shape.center, offset);
    shape.corner = Plus(shape.corner, offset);
    shape.terrain.origin = Plus(shape.terrain.origin, offset);
    for (Vec3& v : shape.mesh.vertices) v = Plus(v, offset);
  }
}

void RebaseOnCamera(Scene& scene) {
  const Vec3 camera = scene.camera.position.Evaluate(scene.render.firstFrame);
  TranslateScene(scene, {-camera.x, -camera.y, -camera.z});
}

}  // namespace tcfarm
