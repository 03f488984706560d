// Rigid and scaling motion over frame time: a shape's, a camera rig's or a light's
// transform at each frame, made of a translation, a rotation (a unit quaternion) and a
// scale about a pivot. The paper's polynomial and keyframed translations are the special
// case with no rotation and unit scale, and are evaluated exactly as before.
#pragma once

#include <memory>
#include <vector>

#include "proto/scene/animated_vec3.h"

namespace tcfarm {

// A rotation as a quaternion w + xi + yj + zk of any non-zero length (it is normalised
// where it is used, so a scene written out and read back keeps its bits).
struct Quaternion {
  double w = 1, x = 0, y = 0, z = 0;
  bool operator==(const Quaternion& o) const { return w == o.w && x == o.x && y == o.y && z == o.z; }
  bool operator!=(const Quaternion& o) const { return !(*this == o); }
  bool IsIdentity() const { return w == 1 && x == 0 && y == 0 && z == 0; }
  // The unit quaternion of `axis` (any length > 0) turned by `degrees`.
  static Quaternion FromAxisAngle(Vec3 axis, double degrees);
};

// Shortest-arc spherical interpolation: t = 0 gives a, t = 1 gives b (up to sign).
Quaternion Slerp(const Quaternion& a, const Quaternion& b, double t);

// An affine map y = linear * x + offset (row-major 3x3 and a column), in double.
struct Affine {
  double linear[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  Vec3 offset;

  Vec3 Apply(const Vec3& p) const;
  Vec3 ApplyLinear(const Vec3& v) const;
  // Largest factor by which the map stretches a length: the largest column norm, exact
  // for a rotation times a scale.
  double MaxStretch() const;
  double Determinant() const;
  // What carries a normal of the object to the world: the inverse transpose of the linear
  // part, so that an outward normal stays outward under a mirror too. Not unit.
  void NormalMatrix(double out[3][3]) const;
  bool operator==(const Affine& o) const;
};

// The cofactor matrix of a linear map: its inverse transpose times its determinant.
void Cofactor(const double m[3][3], double out[3][3]);
Vec3 ApplyMatrix(const double m[3][3], const Vec3& v);

// outer * inner: first inner, then outer.
Affine Compose(const Affine& outer, const Affine& inner);

// A rotation over frame time: constant, keyframed (held before the first and after the
// last key; slerp between keys, or held, or a cubic spline through the quaternions'
// components normalised, as glTF interpolates) or a steady spin about an axis.
class AnimatedRotation {
 public:
  struct Keyframe {
    double frame;
    Quaternion value;
    Quaternion inTangent = {0, 0, 0, 0}, outTangent = {0, 0, 0, 0};  // cubic spline only
  };

  AnimatedRotation() = default;
  static AnimatedRotation Constant(Quaternion value);
  // Keys sorted by frame, no two on one frame, non-zero quaternions (the parser checks).
  static AnimatedRotation Keyframes(std::vector<Keyframe> keys,
                                    Interpolation interpolation = Interpolation::kLinear);
  // degreesAtZero + degreesPerFrame * frame about `axis`.
  static AnimatedRotation Spin(Vec3 axis, double degreesPerFrame, double degreesAtZero = 0);

  Quaternion Evaluate(double frame) const;
  bool IsAnimated() const;

  enum class Kind { kConstant, kKeyframes, kSpin };
  Kind kind() const { return kind_; }
  const Quaternion& constant() const { return constant_; }
  const std::vector<Keyframe>& keys() const { return keys_; }
  const Vec3& axis() const { return axis_; }
  double degreesPerFrame() const { return degreesPerFrame_; }
  double degreesAtZero() const { return degreesAtZero_; }
  Interpolation interpolation() const { return interpolation_; }

 private:
  Kind kind_ = Kind::kConstant;
  Interpolation interpolation_ = Interpolation::kLinear;
  Quaternion constant_;
  std::vector<Keyframe> keys_;
  Vec3 axis_{0, 1, 0};
  double degreesPerFrame_ = 0, degreesAtZero_ = 0;
};

// worldFromObject(f) = parentWorld(f) * Translate(translation(f) + pivot)
//                      * Rotate(rotation(f)) * Scale(scale(f)) * Translate(-pivot).
// The pivot is a point of the object's rest pose (a sphere's centre spins it in place).
// A parent carries the object as a node of a hierarchy is carried by its ancestors.
struct Motion {
  AnimatedVec3 translation;
  AnimatedRotation rotation;
  AnimatedVec3 scale = AnimatedVec3::Constant({1, 1, 1});
  Vec3 pivot;
  std::shared_ptr<const Motion> parent;  // none: the world

  bool IsAnimated() const {
    return translation.IsAnimated() || rotation.IsAnimated() || scale.IsAnimated() ||
           (parent && parent->IsAnimated());
  }
  // The identity at every frame: what a shape, camera rig or light has by default.
  bool IsNone() const {
    return IsTranslationOnly() && !translation.IsAnimated() && translation.Evaluate(0) == Vec3{};
  }
  // No rotation, unit scale and no parent that moves or turns, at any frame: the motion is
  // translation.Evaluate alone.
  bool IsTranslationOnly() const;
  // The same for this node alone, its parent aside.
  bool LocalIsTranslationOnly() const;
  Affine WorldFromObject(double frame) const;
  // This node's own transform, its parent aside.
  Affine LocalFromObject(double frame) const;
  // Whether the transform at frames a and b is the same, bit for bit.
  bool SameAt(double a, double b) const { return WorldFromObject(a) == WorldFromObject(b); }
};

}  // namespace tcfarm
