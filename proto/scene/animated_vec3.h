// Vectors of the scene and their animation over frame time.
#pragma once

#include <algorithm>
#include <array>
#include <vector>

namespace tcfarm {

struct Vec3 {
  double x = 0, y = 0, z = 0;
  double operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  double& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
  bool operator==(const Vec3& o) const { return x == o.x && y == o.y && z == o.z; }
  bool operator!=(const Vec3& o) const { return !(*this == o); }
};

// How keyframes are joined (glTF's three): straight lines; each key held until the next;
// cubic Hermite curves through the keys with per-key tangents (in value per frame).
enum class Interpolation { kLinear, kStep, kCubicSpline };

// The cubic Hermite curve at t in [0, 1] from `from` to `to` over an interval of `span`
// frames, leaving with outTangent and arriving with inTangent (both per frame).
double Hermite(double from, double outTangent, double to, double inTangent, double span, double t);

// Where a frame falls among keyframes sorted by strictly increasing frame (any struct with
// a `frame`): the key at or before it, the key after it and how far along, t in [0, 1).
// Before the first key and after the last the end key is held: `next` is that key too and
// t is 0, so each key is reached only through t == 0 and keeps its bits.
template <typename Key>
struct KeySpan {
  const Key* previous;
  const Key* next;
  double t;
};

template <typename Key>
KeySpan<Key> FindKeySpan(const std::vector<Key>& keys, double frame) {
  if (frame <= keys.front().frame) return {&keys.front(), &keys.front(), 0};
  if (frame >= keys.back().frame) return {&keys.back(), &keys.back(), 0};
  auto after = std::upper_bound(keys.begin(), keys.end(), frame, [](double f, const Key& key) { return f < key.frame; });
  const Key& previous = *(after - 1);
  return {&previous, &*after, (frame - previous.frame) / (after->frame - previous.frame)};
}

// A vec3-valued function of frame time, as in the paper's section 5: either a constant,
// a polynomial per axis in the frame number, or keyframes (held constant before the first
// and after the last key), joined linearly unless told otherwise.
class AnimatedVec3 {
 public:
  struct Keyframe {
    double frame;
    Vec3 value;
    Vec3 inTangent = {}, outTangent = {};  // cubic spline only
  };

  AnimatedVec3() = default;
  static AnimatedVec3 Constant(Vec3 value);
  // coefficients[axis][k] multiplies frame^k.
  static AnimatedVec3 Polynomial(std::array<std::vector<double>, 3> coefficients);
  // Keys must be sorted by frame with no two on the same frame (the parser checks).
  static AnimatedVec3 Keyframes(std::vector<Keyframe> keys, Interpolation interpolation = Interpolation::kLinear);

  Vec3 Evaluate(double frame) const;
  // True when Evaluate can return different values for different frames.
  bool IsAnimated() const;
  // True when Evaluate(a) == Evaluate(b) bit for bit (exact, not approximate).
  bool SameAt(double a, double b) const { return Evaluate(a) == Evaluate(b); }

  enum class Kind { kConstant, kPolynomial, kKeyframes };
  Kind kind() const { return kind_; }
  const std::array<std::vector<double>, 3>& coefficients() const { return coefficients_; }
  const std::vector<Keyframe>& keys() const { return keys_; }
  const Vec3& constant() const { return constant_; }
  Interpolation interpolation() const { return interpolation_; }

 private:
  Kind kind_ = Kind::kConstant;
  Interpolation interpolation_ = Interpolation::kLinear;
  Vec3 constant_;
  std::array<std::vector<double>, 3> coefficients_;
  std::vector<Keyframe> keys_;
};

// The same function moved by `offset` at every frame (a position moved with the world).
AnimatedVec3 Offset(const AnimatedVec3& value, const Vec3& offset);

}  // namespace tcfarm
