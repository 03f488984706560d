#include "proto/scene/animated_vec3.h"

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

AnimatedVec3 AnimatedVec3::Keyframes(std::vector<Keyframe> keys, Interpolation interpolation) {
  AnimatedVec3 result;
  result.kind_ = Kind::kKeyframes;
  result.interpolation_ = interpolation;
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

Vec3 InterpolateKeys(const std::vector<AnimatedVec3::Keyframe>& keys, Interpolation interpolation,
                     double frame) {
  if (keys.empty()) return Vec3{};
  const KeySpan<AnimatedVec3::Keyframe> span = FindKeySpan(keys, frame);
  const auto& previous = *span.previous;
  const auto& next = *span.next;
  const double t = span.t;
  if (t == 0) return previous.value;
  switch (interpolation) {
    case Interpolation::kStep:
      return previous.value;
    case Interpolation::kCubicSpline: {
      const double frames = next.frame - previous.frame;
      Vec3 result;
      for (int axis = 0; axis < 3; ++axis) {
        result[axis] = Hermite(previous.value[axis], previous.outTangent[axis], next.value[axis],
                               next.inTangent[axis], frames, t);
      }
      return result;
    }
    case Interpolation::kLinear:
      break;
  }
  return Vec3{Lerp(previous.value.x, next.value.x, t), Lerp(previous.value.y, next.value.y, t),
              Lerp(previous.value.z, next.value.z, t)};
}

}  // namespace

double Hermite(double from, double outTangent, double to, double inTangent, double span, double t) {
  const double t2 = t * t, t3 = t2 * t;
  return (2 * t3 - 3 * t2 + 1) * from + (t3 - 2 * t2 + t) * span * outTangent + (-2 * t3 + 3 * t2) * to +
         (t3 - t2) * span * inTangent;
}

Vec3 AnimatedVec3::Evaluate(double frame) const {
  switch (kind_) {
    case Kind::kConstant:
      return constant_;
    case Kind::kPolynomial:
      return Vec3{EvaluateHorner(coefficients_[0], frame), EvaluateHorner(coefficients_[1], frame),
                  EvaluateHorner(coefficients_[2], frame)};
    case Kind::kKeyframes:
      return InterpolateKeys(keys_, interpolation_, frame);
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
        // A curve through equal keys still moves between them when it leaves with a slope.
        if (interpolation_ == Interpolation::kCubicSpline && (key.inTangent != Vec3{} || key.outTangent != Vec3{})) {
          return true;
        }
      }
      return false;
  }
  return false;
}

namespace {

Vec3 Plus(const Vec3& a, const Vec3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }

}  // namespace

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

}  // namespace tcfarm
