// glTF 2.0's BRDF (the specification's Appendix B), as shading evaluates it for one light:
// a Lambertian diffuse lobe and a GGX specular lobe (alpha = roughness^2, the
// height-correlated Smith visibility), mixed by Schlick's Fresnel between a dielectric
// (f0 from the index of refraction, weighted by KHR_materials_specular) and a metal (f0 =
// the base colour); under KHR_materials_clearcoat's coat, a second GGX lobe on top. Inline and in float: it is asked for every lit hit.
#pragma once

#include <algorithm>
#include <cmath>

#include "worker/trace/float3.h"

namespace tcfarm {

constexpr float kInversePi = 0.318309886183790671538f;

// What the BRDF needs of a surface point, once its textures are read.
// A tag: a surface whose fields the caller writes (a hit's, filled only for glTF materials).
struct Unset {};

struct PbrSurface {
  Float3 baseColor;  // linear
  float metallic, roughness;
  float occlusion;  // 1: none (weighs the ambient term only)
  float alpha;      // coverage (base colour alpha), for a blended material
  Float3 emission;  // linear radiance the surface shows of itself
  // KHR_materials_clearcoat: the coat's weight (0: none), roughness and unit normal.
  float clearcoat, clearcoatRoughness;
  Float3 clearcoatNormal;

  PbrSurface() : metallic(1), roughness(1), occlusion(1), alpha(1), clearcoat(0), clearcoatRoughness(0) {}
  // Left unwritten: every hit carries one, and a Phong hit never reads it.
  explicit PbrSurface(Unset) {}
};

// What a material fixes for every point of it.
struct PbrConstants {
  Float3 dielectricF0{0.04f, 0.04f, 0.04f};  // ((ior - 1) / (ior + 1))^2 * specular colour * specular
  float dielectricF90 = 1;                   // KHR_materials_specular's factor (1 without it)
};

inline Float3 Mix(Float3 a, Float3 b, float t) { return a * (1.0f - t) + b * t; }

// Schlick's Fresnel at cosine `cosine` between f0 and f90.
inline Float3 Schlick(Float3 f0, Float3 f90, float cosine) {
  const float m = std::clamp(1.0f - cosine, 0.0f, 1.0f);
  const float m2 = m * m;
  return f0 + (f90 - f0) * (m2 * m2 * m);
}

inline Float3 SurfaceF0(const PbrSurface& s, const PbrConstants& c) { return Mix(c.dielectricF0, s.baseColor, s.metallic); }
inline Float3 SurfaceF90(const PbrSurface& s, const PbrConstants& c) {
  const float f90 = c.dielectricF90 + (1.0f - c.dielectricF90) * s.metallic;
  return {f90, f90, f90};
}

// alpha = roughness^2, kept above 1e-3: a perfectly smooth surface's lobe is a spike that
// would divide zero by zero where the half vector meets the normal (its mirror ray, not the
// lobe, shows what it reflects).
inline float GgxAlpha(float roughness) { return std::max(roughness * roughness, 1e-3f); }

// GGX's normal distribution, alpha = roughness^2.
inline float GgxDistribution(float nDotH, float alpha) {
  const float a2 = alpha * alpha;
  const float f = nDotH * nDotH * (a2 - 1.0f) + 1.0f;
  return a2 * kInversePi / (f * f);
}

// Smith-GGX visibility, height-correlated (V = G / (4 NdotL NdotV)).
inline float SmithVisibility(float nDotL, float nDotV, float alpha) {
  const float a2 = alpha * alpha;
  const float ggxV = nDotL * std::sqrt(nDotV * nDotV * (1.0f - a2) + a2);
  const float ggxL = nDotV * std::sqrt(nDotL * nDotL * (1.0f - a2) + a2);
  const float sum = ggxV + ggxL;
  return sum > 0 ? 0.5f / sum : 0.0f;
}

// The material under any coat (PbrReflected below): its BRDF times the cosine at its unit
// shading `normal`.
inline Float3 UncoatedReflected(const PbrSurface& s, const PbrConstants& c, Float3 towardLight, Float3 normal,
                                Float3 towardViewer) {
  const float nDotL = Dot(normal, towardLight);
  if (!(nDotL > 0)) return {};
  // A normal map can tilt the normal away from a viewer who sees the face: seen edge-on.
  const float nDotV = std::max(Dot(normal, towardViewer), 1e-4f);
  Float3 half = towardLight + towardViewer;
  const float halfLength = Length(half);
  half = halfLength > 0 ? half * (1.0f / halfLength) : normal;
  const float nDotH = std::max(Dot(normal, half), 0.0f);
  const float vDotH = std::max(Dot(towardViewer, half), 0.0f);
  // Appendix B: mix(dielectric, metal, metallic), where the dielectric splits its light by
  // its own Fresnel term and the metal has no diffuse lobe. Schlick's term is linear in f0,
  // so the two specular lobes fold into one with the mixed f0.
  const Float3 fresnel = Schlick(SurfaceF0(s, c), SurfaceF90(s, c), vDotH);
  const Float3 dielectricFresnel =
      Schlick(c.dielectricF0, {c.dielectricF90, c.dielectricF90, c.dielectricF90}, vDotH);
  const float alpha = GgxAlpha(s.roughness);
  const Float3 diffuseColor = s.baseColor * (1.0f - s.metallic);
  const Float3 diffuse = (Float3{1, 1, 1} - dielectricFresnel) * diffuseColor * kInversePi;
  const Float3 specular = fresnel * (GgxDistribution(nDotH, alpha) * SmithVisibility(nDotL, nDotV, alpha));
  return (diffuse + specular) * nDotL;
}

// KHR_materials_clearcoat's coat: a dielectric of index 1.5 (f0 0.04, f90 1).
constexpr float kClearcoatF0 = 0.04f;

// The share of light the coat reflects toward a viewer at cosine `nDotV` to the coat's
// normal (Schlick); the layer below gets the rest. At the viewing angle, not per light's
// half vector, as the Khronos Sample Renderer has it: the same weight then serves lights,
// mirror rays and emission.
inline float ClearcoatWeight(const PbrSurface& s, Float3 towardViewer) {
  const float nDotV = std::max(Dot(s.clearcoatNormal, towardViewer), 0.0f);
  return s.clearcoat * Schlick({kClearcoatF0, kClearcoatF0, kClearcoatF0}, {1, 1, 1}, nDotV).x;
}

// The coat's GGX lobe over its own normal and roughness, without its Fresnel term (the
// weight carries it), times the cosine to its normal.
inline float ClearcoatLobe(const PbrSurface& s, Float3 towardLight, Float3 towardViewer) {
  const Float3 n = s.clearcoatNormal;
  const float nDotL = Dot(n, towardLight);
  if (!(nDotL > 0)) return 0;
  const float nDotV = std::max(Dot(n, towardViewer), 1e-4f);
  Float3 half = towardLight + towardViewer;
  const float halfLength = Length(half);
  half = halfLength > 0 ? half * (1.0f / halfLength) : n;
  const float alpha = s.clearcoatRoughness * s.clearcoatRoughness;
  return GgxDistribution(std::max(Dot(n, half), 0.0f), alpha) * SmithVisibility(nDotL, nDotV, alpha) * nDotL;
}

// Radiance reflected toward unit `towardViewer` from light of unit irradiance (at normal
// incidence) arriving from unit `towardLight`: the material's BRDF times the cosine at its
// unit shading `normal`, and where it is coated, mixed with the coat's lobe by the coat's
// weight w: (1 - w) base + w coat.
inline Float3 PbrReflected(const PbrSurface& s, const PbrConstants& c, Float3 towardLight, Float3 normal,
                           Float3 towardViewer) {
  const Float3 base = UncoatedReflected(s, c, towardLight, normal, towardViewer);
  if (!(s.clearcoat > 0)) return base;
  const float weight = ClearcoatWeight(s, towardViewer);
  const float coat = ClearcoatLobe(s, towardLight, towardViewer) * weight;
  return base * (1.0f - weight) + Float3{coat, coat, coat};
}

}  // namespace tcfarm
