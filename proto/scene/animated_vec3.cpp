#include "scene/animated_vec3.h"

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

}  // namespace tcfarm
