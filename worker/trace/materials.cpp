#include "trace/materials.h"

#include <cmath>

namespace tcfarm {

Float3 ShadingMaterial::Reflected(Float3 towardLight, Float3 normal, Float3 arriving, Float3 surfaceDiffuse) const {
  float cosine = Dot(towardLight, normal);
  Float3 color = surfaceDiffuse * cosine;
  if (specular.x > 0 || specular.y > 0 || specular.z > 0) {
    float highlight = Dot(Reflect(-towardLight, normal), -arriving);
    if (highlight > 0) color += specular * std::pow(highlight, shininess);
  }
  return color;
}

std::vector<ShadingMaterial> MakeMaterials(const Scene& scene) {
  std::vector<ShadingMaterial> materials;
  for (const Material& m : scene.materials) {
    materials.push_back({ToFloat3(m.diffuse), ToFloat3(m.specular), static_cast<float>(m.shininess),
                         static_cast<float>(m.reflectivity), static_cast<float>(m.transparency),
                         static_cast<float>(m.indexOfRefraction), ToFloat3(m.emission), m.emission != Vec3{}});
  }
  return materials;
}

bool Refract(Float3 arriving, Float3 normal, float eta, Float3* refracted) {
  float cosIn = -Dot(arriving, normal);
  float k = 1.0f - eta * eta * (1.0f - cosIn * cosIn);
  if (k < 0) return false;
  *refracted = Normalize(arriving * eta + normal * (eta * cosIn - std::sqrt(k)));
  return true;
}

}  // namespace tcfarm
