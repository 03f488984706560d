#include "worker/trace/materials/gltf_material.h"

#include <cmath>

namespace tcfarm {

PbrTexture PbrMaterial::MakeTexture(const std::optional<TextureSlot>& slot, TextureImage::Encoding encoding,
                                    const TextureLoader& load) {
  PbrTexture texture;
  if (!slot) return texture;
  texture.image = load(slot->texture, encoding);
  texture.texCoord = slot->texCoord;
  texture.amount = static_cast<float>(slot->amount);
  texture.transformed = slot->Transformed();
  // KHR_texture_transform: uv' = T(offset) R(rotation) S(scale) uv, R = [cos sin; -sin cos].
  const double c = std::cos(slot->rotation), s = std::sin(slot->rotation);
  texture.m00 = static_cast<float>(c * slot->scale[0]);
  texture.m01 = static_cast<float>(s * slot->scale[1]);
  texture.m10 = static_cast<float>(-s * slot->scale[0]);
  texture.m11 = static_cast<float>(c * slot->scale[1]);
  texture.du = static_cast<float>(slot->offset[0]);
  texture.dv = static_cast<float>(slot->offset[1]);
  if (!texture.image) return texture;  // not loaded: a material no shape uses
  const double texels = static_cast<double>(texture.image->width()) * texture.image->height();
  const double scale = texture.transformed ? std::fabs(slot->scale[0] * slot->scale[1]) : 1.0;
  texture.lodBias = static_cast<float>(0.5 * std::log2(texels * scale));
  return texture;
}

PbrMaterial::PbrMaterial(const MetallicRoughness& m, const TextureLoader& load)
    : baseColor(ToFloat3(m.baseColor)),
      metallic(static_cast<float>(m.metallic)),
      roughness(static_cast<float>(m.roughness)),
      emissive(ToFloat3(m.emissive) * static_cast<float>(m.emissiveStrength)),
      transmission(static_cast<float>(m.transmission)),
      indexOfRefraction(static_cast<float>(m.ior)),
      unlit(m.unlit),
      alpha(static_cast<float>(m.alpha)),
      blends(m.alphaMode == MetallicRoughness::Alpha::kBlend) {
  const double r = (m.ior - 1) / (m.ior + 1);
  const Vec3 f0{std::min(r * r * m.specularColor.x, 1.0), std::min(r * r * m.specularColor.y, 1.0),
                std::min(r * r * m.specularColor.z, 1.0)};
  constants.dielectricF0 = ToFloat3(f0) * static_cast<float>(m.specular);
  constants.dielectricF90 = static_cast<float>(m.specular);
  using Encoding = TextureImage::Encoding;
  baseColorTexture = MakeTexture(m.baseColorTexture, Encoding::kSrgb, load);
  emissiveTexture = MakeTexture(m.emissiveTexture, Encoding::kSrgb, load);
  if (!unlit) LoadLitTextures(m, load);  // an unlit surface reads its base colour only
  for (const PbrTexture* texture : {&baseColorTexture, &metallicRoughnessTexture, &normalTexture, &occlusionTexture,
                                    &emissiveTexture, &clearcoatTexture, &clearcoatRoughnessTexture,
                                    &clearcoatNormalTexture}) {
    if (!*texture) continue;
    textured_ = true;
    readsTexCoord_[texture->texCoord == 1] = true;
  }
}

void PbrMaterial::LoadLitTextures(const MetallicRoughness& m, const TextureLoader& load) {
  using Encoding = TextureImage::Encoding;
  metallicRoughnessTexture = MakeTexture(m.metallicRoughnessTexture, Encoding::kLinear, load);
  normalTexture = MakeTexture(m.normalTexture, Encoding::kLinear, load);
  occlusionTexture = MakeTexture(m.occlusionTexture, Encoding::kLinear, load);
  if (m.clearcoat > 0) {
    clearcoat = static_cast<float>(m.clearcoat);
    clearcoatRoughness = static_cast<float>(m.clearcoatRoughness);
    clearcoatTexture = MakeTexture(m.clearcoatTexture, Encoding::kLinear, load);
    clearcoatRoughnessTexture = MakeTexture(m.clearcoatRoughnessTexture, Encoding::kLinear, load);
    clearcoatNormalTexture = MakeTexture(m.clearcoatNormalTexture, Encoding::kLinear, load);
  }
}

PbrSurface PbrMaterial::Surface(std::array<float, 2> uv0, std::array<float, 2> uv1, Float3 vertexColor,
                                const UvFootprint& footprint) const {
  auto uvOf = [&](const PbrTexture& t) { return t.texCoord == 1 ? uv1 : uv0; };
  PbrSurface s;
  s.baseColor = baseColor * vertexColor;
  if (baseColorTexture) s.baseColor = s.baseColor * baseColorTexture.Sample(uvOf(baseColorTexture), footprint);
  if (blends) s.alpha = baseColorTexture ? alpha * baseColorTexture.SampleAlpha(uvOf(baseColorTexture), footprint) : alpha;
  s.metallic = metallic;
  s.roughness = roughness;
  if (metallicRoughnessTexture) {
    const Float3 texel = metallicRoughnessTexture.Sample(uvOf(metallicRoughnessTexture), footprint);
    s.metallic = std::clamp(metallic * texel.z, 0.0f, 1.0f);
    s.roughness = std::clamp(roughness * texel.y, 0.0f, 1.0f);
  }
  if (occlusionTexture) {
    const float occluded = occlusionTexture.Sample(uvOf(occlusionTexture), footprint).x;
    s.occlusion = 1.0f + occlusionTexture.amount * (occluded - 1.0f);
  }
  s.emission = emissive;
  if (emissiveTexture) s.emission = s.emission * emissiveTexture.Sample(uvOf(emissiveTexture), footprint);
  if (clearcoat > 0) {
    s.clearcoat = clearcoat;
    if (clearcoatTexture) s.clearcoat *= clearcoatTexture.Sample(uvOf(clearcoatTexture), footprint).x;
    s.clearcoatRoughness = clearcoatRoughness;
    if (clearcoatRoughnessTexture) {
      s.clearcoatRoughness = std::clamp(clearcoatRoughness * clearcoatRoughnessTexture.Sample(uvOf(clearcoatRoughnessTexture), footprint).y, 0.0f, 1.0f);
    }
  }
  return s;
}

}  // namespace tcfarm
