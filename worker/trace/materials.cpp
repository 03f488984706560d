#include "worker/trace/materials.h"

#include <cmath>

namespace tcfarm {

std::vector<ShadingMaterial> MakeMaterials(const Scene& scene, const TextureLoader& load) {
  std::vector<ShadingMaterial> materials;
  for (const Material& m : scene.materials) {
    ShadingMaterial s{ToFloat3(m.diffuse), ToFloat3(m.specular), static_cast<float>(m.shininess),
                      static_cast<float>(m.reflectivity), static_cast<float>(m.transparency),
                      static_cast<float>(m.indexOfRefraction), ToFloat3(m.emission), m.emission != Vec3{}, false, PbrMaterial{}};
    if (m.pbr) {
      s.pbr = true;
      s.gltf = PbrMaterial(*m.pbr, load);
      s.diffuse = s.gltf.baseColor;
    }
    materials.push_back(s);
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
