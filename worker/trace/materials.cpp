#include "worker/trace/materials.h"

#include <cmath>

namespace tcfarm {

std::vector<ShadingMaterial> MakeMaterials(const Scene& scene, const TextureLoader& load) {
  // Only the images of materials some shape uses are decoded.
  std::vector<bool> used(scene.materials.size(), false);
  for (const Shape& shape : scene.shapes) used[static_cast<size_t>(shape.material)] = true;
  const TextureLoader none = [](const Texture&, TextureImage::Encoding) { return nullptr; };
  std::vector<ShadingMaterial> materials;
  for (size_t i = 0; i < scene.materials.size(); ++i) {
    const Material& m = scene.materials[i];
    ShadingMaterial s{ToFloat3(m.diffuse), ToFloat3(m.specular), static_cast<float>(m.shininess),
                      static_cast<float>(m.reflectivity), static_cast<float>(m.transparency),
                      static_cast<float>(m.indexOfRefraction), ToFloat3(m.emission), m.emission != Vec3{}, false, PbrMaterial{}};
    if (m.pbr) {
      s.pbr = true;
      s.gltf = PbrMaterial(*m.pbr, used[i] ? load : none);
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
