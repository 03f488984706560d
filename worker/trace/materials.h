// Materials as shading sees them, one struct per model: the Whitted model's Phong terms
// (diffuse and specular, an ambient term, mirror reflection and refraction weights), here;
// glTF's metallic-roughness model in materials/gltf_material.h, its BRDF in
// materials/gltf_brdf.h. A new model adds its files there and a case where the tracer asks
// `pbr` (worker/trace/tracer.cpp: MakeHit, Ambient, LightContribution, Combine).
#pragma once

#include <cmath>
#include <vector>

#include "proto/scene/scene.h"
#include "worker/trace/float3.h"
#include "worker/trace/materials/gltf_material.h"

namespace tcfarm {

// Fraction of a material's diffuse colour seen with no light at all, so surfaces in
// shadow keep their shape (Whitted's ambient term).
constexpr float kAmbient = 0.05f;

struct ShadingMaterial {
  Float3 diffuse, specular;
  float shininess, reflectivity, transparency, indexOfRefraction;
  Float3 emission;
  bool emits;
  // glTF's model instead of the fields above
  bool pbr = false;
  PbrMaterial gltf;

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
  bool MirrorsOrRefracts() const {
    return pbr ? gltf.MayContinue() : reflectivity != 0 || transparency != 0;
  }
};

// `load` decodes the textures glTF materials use (Phong's are the tracer's own table).
std::vector<ShadingMaterial> MakeMaterials(const Scene& scene, const TextureLoader& load);

// The refracted direction of unit `arriving` through a surface of unit `normal` (facing
// the arriving ray) with relative index eta; false for total internal reflection.
bool Refract(Float3 arriving, Float3 normal, float eta, Float3* refracted);

}  // namespace tcfarm
