// Single-precision 3-vectors for the shading hot path. Scene data stays in double
// (proto/scene); it is converted once per frame, when the frame's geometry is placed.
#pragma once

#include <algorithm>
#include <cmath>

#include "proto/scene/scene.h"

namespace tcfarm {

struct Float3 {
  float x = 0, y = 0, z = 0;
};

inline Float3 operator+(Float3 a, Float3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline Float3 operator-(Float3 a, Float3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Float3 operator-(Float3 a) { return {-a.x, -a.y, -a.z}; }
inline Float3 operator*(Float3 a, float s) { return {a.x * s, a.y * s, a.z * s}; }
inline Float3 operator*(float s, Float3 a) { return a * s; }
inline Float3 operator*(Float3 a, Float3 b) { return {a.x * b.x, a.y * b.y, a.z * b.z}; }
inline Float3& operator+=(Float3& a, Float3 b) { return a = a + b; }
inline float Dot(Float3 a, Float3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Float3 Cross(Float3 a, Float3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline float Length(Float3 a) { return std::sqrt(Dot(a, a)); }
inline Float3 Normalize(Float3 a) { return a * (1.0f / Length(a)); }
inline float MaxAbsComponent(Float3 a) {
  return std::max(std::fabs(a.x), std::max(std::fabs(a.y), std::fabs(a.z)));
}
inline Float3 ToFloat3(const Vec3& v) {
  return {static_cast<float>(v.x), static_cast<float>(v.y), static_cast<float>(v.z)};
}
// Double-precision helpers for what is built from the scene once per frame (the camera
// basis, light directions), where float would lose digits far from the origin.
inline Vec3 SubtractD(const Vec3& a, const Vec3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline double DotD(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3 CrossD(const Vec3& a, const Vec3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline Vec3 NormalizeD(const Vec3& a) {
  double length = std::sqrt(a.x * a.x + a.y * a.y + a.z * a.z);
  return {a.x / length, a.y / length, a.z / length};
}
// Mirror direction of `incident` (pointing at the surface) about unit normal n.
inline Float3 Reflect(Float3 incident, Float3 n) { return incident - n * (2.0f * Dot(incident, n)); }
// The refracted direction of unit `arriving` through a surface of unit `normal` (facing
// the arriving ray) with relative index eta; false for total internal reflection.
inline bool Refract(Float3 arriving, Float3 normal, float eta, Float3* refracted) {
  float cosIn = -Dot(arriving, normal);
  float k = 1.0f - eta * eta * (1.0f - cosIn * cosIn);
  if (k < 0) return false;
  *refracted = Normalize(arriving * eta + normal * (eta * cosIn - std::sqrt(k)));
  return true;
}

}  // namespace tcfarm
