// The Whitted model's materials as shading sees them: Phong's diffuse and specular terms,
// an ambient term, mirror reflection and refraction weights.
#pragma once

#include <cmath>
#include <vector>

#include "proto/scene/scene.h"
#include "worker/trace/float3.h"

namespace tcfarm {

// Fraction of a material's diffuse colour seen with no light at all, so surfaces in
// shadow keep their shape (Whitted's ambient term).
constexpr float kAmbient = 0.05f;

struct ShadingMaterial {
  Float3 diffuse, specular;
  float shininess, reflectivity, transparency, indexOfRefraction;
  Float3 emission;
  bool emits;

  // With `surfaceDiffuse` the diffuse colour at the hit (the material's, or textured).
  static Float3 Ambient(Float3 surfaceDiffuse) { return surfaceDiffuse * kAmbient; }
  // Phong: light of unit intensity arriving from unit direction `towardLight` at a surface
  // of unit `normal`, seen by a ray arriving along unit `arriving`.
  // Inline: asked for every lit hit.
  Float3 Reflected(Float3 towardLight, Float3 normal, Float3 arriving, Float3 surfaceDiffuse) const {
    float cosine = Dot(towardLight, normal);
    Float3 color = surfaceDiffuse * cosine;
    if (specular.x > 0 || specular.y > 0 || specular.z > 0) {
      float highlight = Dot(Reflect(-towardLight, normal), -arriving);
      if (highlight > 0) color += specular * std::pow(highlight, shininess);
    }
    return color;
  }
  bool MirrorsOrRefracts() const { return reflectivity != 0 || transparency != 0; }
};

std::vector<ShadingMaterial> MakeMaterials(const Scene& scene);

// The refracted direction of unit `arriving` through a surface of unit `normal` (facing
// the arriving ray) with relative index eta; false for total internal reflection.
bool Refract(Float3 arriving, Float3 normal, float eta, Float3* refracted);

}  // namespace tcfarm
