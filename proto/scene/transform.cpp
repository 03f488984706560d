#include "proto/scene/transform.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace tcfarm {
namespace {

Quaternion Normalized(Quaternion q) {
  double length = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
  return {q.w / length, q.x / length, q.y / length, q.z / length};
}

// The rotation matrix of a quaternion of any non-zero length, row-major. Quaternions are
// kept as the scene gives them and normalised here, by the 2 / |q|^2 factor: normalising
// at parse time would change the last bits of a scene written out and read back.
void RotationMatrix(const Quaternion& q, double m[3][3]) {
  const double s = 2 / (q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
  const double xx = q.x * q.x, yy = q.y * q.y, zz = q.z * q.z;
  const double xy = q.x * q.y, xz = q.x * q.z, yz = q.y * q.z;
  const double wx = q.w * q.x, wy = q.w * q.y, wz = q.w * q.z;
  m[0][0] = 1 - s * (yy + zz), m[0][1] = s * (xy - wz), m[0][2] = s * (xz + wy);
  m[1][0] = s * (xy + wz), m[1][1] = 1 - s * (xx + zz), m[1][2] = s * (yz - wx);
  m[2][0] = s * (xz - wy), m[2][1] = s * (yz + wx), m[2][2] = 1 - s * (xx + yy);
}

}  // namespace

Quaternion Quaternion::FromAxisAngle(Vec3 axis, double degrees) {
  double length = std::sqrt(axis.x * axis.x + axis.y * axis.y + axis.z * axis.z);
  double half = degrees * M_PI / 360.0;
  double s = std::sin(half) / length;
  return {std::cos(half), axis.x * s, axis.y * s, axis.z * s};
}

namespace {

// glTF's cubic spline for rotations: the components' Hermite curves, normalised.
Quaternion CubicKeys(const AnimatedRotation::Keyframe& previous, const AnimatedRotation::Keyframe& next, double t) {
  const double span = next.frame - previous.frame;
  auto component = [&](double Quaternion::*part) {
    return Hermite(previous.value.*part, previous.outTangent.*part, next.value.*part, next.inTangent.*part, span, t);
  };
  Quaternion q{component(&Quaternion::w), component(&Quaternion::x), component(&Quaternion::y),
               component(&Quaternion::z)};
  const double squared = q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z;
  return squared > 0 ? q : previous.value;  // a curve through zero has no direction there
}

}  // namespace

Quaternion Slerp(const Quaternion& a0, const Quaternion& b0, double t) {
  if (t == 0) return a0;  // a key is reached exactly, so a still key holds its bits
  const Quaternion a = Normalized(a0);
  Quaternion b = Normalized(b0);
  double cosine = a.w * b.w + a.x * b.x + a.y * b.y + a.z * b.z;
  if (cosine < 0) {  // the shorter way round
    cosine = -cosine;
    b = {-b.w, -b.x, -b.y, -b.z};
  }
  double wa, wb;
  if (cosine > 0.9995) {  // nearly equal: lerp, normalised below, avoids dividing by ~0
    wa = 1 - t;
    wb = t;
  } else {
    double angle = std::acos(cosine);
    double sine = std::sin(angle);
    wa = std::sin((1 - t) * angle) / sine;
    wb = std::sin(t * angle) / sine;
  }
  return Normalized({wa * a.w + wb * b.w, wa * a.x + wb * b.x, wa * a.y + wb * b.y, wa * a.z + wb * b.z});
}

Vec3 Affine::Apply(const Vec3& p) const {
  Vec3 v = ApplyLinear(p);
  return {v.x + offset.x, v.y + offset.y, v.z + offset.z};
}

Vec3 Affine::ApplyLinear(const Vec3& v) const { return ApplyMatrix(linear, v); }

double Affine::MaxStretch() const {
  double largest = 0;
  for (int column = 0; column < 3; ++column) {
    double squared = 0;
    for (int row = 0; row < 3; ++row) squared += linear[row][column] * linear[row][column];
    largest = std::max(largest, squared);
  }
  return std::sqrt(largest);
}

void Cofactor(const double m[3][3], double out[3][3]) {
  for (int row = 0; row < 3; ++row) {
    for (int column = 0; column < 3; ++column) {
      const int r1 = (row + 1) % 3, r2 = (row + 2) % 3, c1 = (column + 1) % 3, c2 = (column + 2) % 3;
      out[row][column] = m[r1][c1] * m[r2][c2] - m[r1][c2] * m[r2][c1];
    }
  }
}

Vec3 ApplyMatrix(const double m[3][3], const Vec3& v) {
  return {m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z, m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
          m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z};
}

namespace {

// Expanded along the first row, whose cofactors `cofactor` holds.
double DeterminantFrom(const double m[3][3], const double cofactor[3][3]) {
  return m[0][0] * cofactor[0][0] + m[0][1] * cofactor[0][1] + m[0][2] * cofactor[0][2];
}

}  // namespace

double Affine::Determinant() const {
  double cofactor[3][3];
  Cofactor(linear, cofactor);
  return DeterminantFrom(linear, cofactor);
}

void Affine::NormalMatrix(double out[3][3]) const {
  Cofactor(linear, out);
  const double determinant = DeterminantFrom(linear, out);
  for (int row = 0; row < 3; ++row) {
    for (int column = 0; column < 3; ++column) out[row][column] /= determinant;
  }
}

bool Affine::operator==(const Affine& o) const {
  for (int row = 0; row < 3; ++row) {
    for (int column = 0; column < 3; ++column) {
      if (linear[row][column] != o.linear[row][column]) return false;
    }
  }
  return offset == o.offset;
}

AnimatedRotation AnimatedRotation::Constant(Quaternion value) {
  AnimatedRotation result;
  result.kind_ = Kind::kConstant;
  result.constant_ = value;
  return result;
}

AnimatedRotation AnimatedRotation::Keyframes(std::vector<Keyframe> keys, Interpolation interpolation) {
  AnimatedRotation result;
  result.kind_ = Kind::kKeyframes;
  result.interpolation_ = interpolation;
  result.keys_ = std::move(keys);
  return result;
}

AnimatedRotation AnimatedRotation::Spin(Vec3 axis, double degreesPerFrame, double degreesAtZero) {
  AnimatedRotation result;
  result.kind_ = Kind::kSpin;
  result.axis_ = axis;
  result.degreesPerFrame_ = degreesPerFrame;
  result.degreesAtZero_ = degreesAtZero;
  return result;
}

Quaternion AnimatedRotation::Evaluate(double frame) const {
  switch (kind_) {
    case Kind::kConstant:
      return constant_;
    case Kind::kSpin:
      return Quaternion::FromAxisAngle(axis_, degreesAtZero_ + degreesPerFrame_ * frame);
    case Kind::kKeyframes: {
      if (keys_.empty()) return {};
      const KeySpan<Keyframe> span = FindKeySpan(keys_, frame);
      const Keyframe& previous = *span.previous;
      if (interpolation_ == Interpolation::kStep || span.t == 0) return previous.value;
      if (interpolation_ == Interpolation::kCubicSpline) return CubicKeys(previous, *span.next, span.t);
      if (previous.value == span.next->value) return previous.value;  // held: bit-identical
      return Slerp(previous.value, span.next->value, span.t);
    }
  }
  return constant_;
}

bool AnimatedRotation::IsAnimated() const {
  switch (kind_) {
    case Kind::kConstant:
      return false;
    case Kind::kSpin:
      return degreesPerFrame_ != 0;
    case Kind::kKeyframes:
      return std::any_of(keys_.begin(), keys_.end(), [&](const Keyframe& key) {
        const Quaternion zero{0, 0, 0, 0};
        return key.value != keys_.front().value ||
               (interpolation_ == Interpolation::kCubicSpline && (key.inTangent != zero || key.outTangent != zero));
      });
  }
  return false;
}

bool Motion::LocalIsTranslationOnly() const {
  return !rotation.IsAnimated() && rotation.Evaluate(0).IsIdentity() && !scale.IsAnimated() &&
         scale.Evaluate(0) == Vec3{1, 1, 1};
}

bool Motion::IsTranslationOnly() const { return LocalIsTranslationOnly() && (!parent || parent->IsNone()); }

Affine Compose(const Affine& outer, const Affine& inner) {
  Affine result;
  for (int row = 0; row < 3; ++row) {
    for (int column = 0; column < 3; ++column) {
      result.linear[row][column] = outer.linear[row][0] * inner.linear[0][column] +
                                   outer.linear[row][1] * inner.linear[1][column] +
                                   outer.linear[row][2] * inner.linear[2][column];
    }
  }
  result.offset = outer.Apply(inner.offset);
  return result;
}

Affine Motion::WorldFromObject(double frame) const {
  Affine local = LocalFromObject(frame);
  return parent && !parent->IsNone() ? Compose(parent->WorldFromObject(frame), local) : local;
}

Affine Motion::LocalFromObject(double frame) const {
  const Vec3 move = translation.Evaluate(frame);
  Affine result;
  if (LocalIsTranslationOnly()) {
    result.offset = move;  // as the paper's motion always was: no pivot arithmetic
    return result;
  }
  double rotation3[3][3];
  RotationMatrix(rotation.Evaluate(frame), rotation3);
  const Vec3 s = scale.Evaluate(frame);
  for (int row = 0; row < 3; ++row) {
    for (int column = 0; column < 3; ++column) result.linear[row][column] = rotation3[row][column] * s[column];
  }
  // offset = translation + pivot - linear * pivot
  const Vec3 turned = result.ApplyLinear(pivot);
  result.offset = {move.x + pivot.x - turned.x, move.y + pivot.y - turned.y, move.z + pivot.z - turned.z};
  return result;
}

}  // namespace tcfarm
