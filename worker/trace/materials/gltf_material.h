// A glTF metallic-roughness material (proto/scene/material.h) as shading reads it: its
// factors in float, and for each texture the decoded image, the texture coordinates it
// reads and their KHR_texture_transform. Surface() turns them into the BRDF's inputs at
// one hit.
#pragma once

#include <array>
#include <functional>

#include "proto/scene/material.h"
#include "worker/trace/float3.h"
#include "worker/trace/materials/gltf_brdf.h"
#include "worker/trace/ray_cone.h"
#include "worker/trace/textures.h"

namespace tcfarm {

// One texture of a material, ready to sample.
struct PbrTexture {
  const TextureImage* image = nullptr;  // null: the material has none
  int texCoord = 0;
  bool transformed = false;
  float m00 = 1, m01 = 0, m10 = 0, m11 = 1, du = 0, dv = 0;  // uv' = [m00 m01; m10 m11] uv + [du dv]
  float amount = 1;                                     // normal scale, occlusion strength
  // What turns a footprint's log2 width in texture coordinates into a mip level: log2 of
  // the image's size in texels (the square root of its texel count) and of the transform's
  // scale (the square root of its determinant's magnitude).
  float lodBias = 0;

  explicit operator bool() const { return image != nullptr; }
  // The texture's value (and alpha) at texture coordinates `uv` (after its transform),
  // filtered over `footprint` (UvFootprint{}: a point, the full image's texels).
  Float3 Sample(std::array<float, 2> uv, const UvFootprint& footprint = {}) const {
    uv = Transformed(uv);
    return image->Sample(uv[0], uv[1], Lod(footprint));
  }
  float SampleAlpha(std::array<float, 2> uv, const UvFootprint& footprint = {}) const {
    uv = Transformed(uv);
    return image->SampleAlpha(uv[0], uv[1], Lod(footprint));
  }
  float Lod(const UvFootprint& footprint) const { return footprint.log2Width[texCoord == 1 ? 1 : 0] + lodBias; }
  std::array<float, 2> Transformed(std::array<float, 2> uv) const {
    if (!transformed) return uv;
    return {m00 * uv[0] + m01 * uv[1] + du, m10 * uv[0] + m11 * uv[1] + dv};
  }
};

struct PbrMaterial {
  Float3 baseColor;
  float metallic = 1, roughness = 1;
  Float3 emissive;  // factor times KHR_materials_emissive_strength
  PbrConstants constants;
  float transmission = 0, indexOfRefraction = 1.5f;
  bool unlit = false;
  float alpha = 1;
  bool blends = false;  // alphaMode BLEND: light passes through by 1 - alpha
  float clearcoat = 0, clearcoatRoughness = 0;  // KHR_materials_clearcoat; 0: no coat
  PbrTexture baseColorTexture, metallicRoughnessTexture, normalTexture, occlusionTexture, emissiveTexture;
  PbrTexture clearcoatTexture, clearcoatRoughnessTexture, clearcoatNormalTexture;

  PbrMaterial() = default;
  PbrMaterial(const MetallicRoughness& source, const TextureLoader& load);

  // Fixed at construction: asked for every hit (textured) and every shape of a task.
  bool Textured() const { return textured_; }
  bool ReadsTexCoord(int set) const { return readsTexCoord_[set == 1]; }
  // Whether its smooth surfaces trace a mirror ray: possibly smooth somewhere.
  bool MaySmooth() const {
    return !unlit && (roughness < kMirrorRoughness || metallicRoughnessTexture || MayCoatSmoothly());
  }
  bool MayCoatSmoothly() const {
    return clearcoat > 0 && (clearcoatRoughness < kMirrorRoughness || clearcoatRoughnessTexture);
  }
  bool Transmits() const { return !unlit && transmission > 0 && metallic < 1; }
  bool MayContinue() const { return MaySmooth() || Transmits() || blends; }

  // The BRDF's inputs at a point with texture coordinates uv0, uv1 and vertex colour
  // `vertexColor` (white where the mesh has none), its textures filtered over `footprint`.
  PbrSurface Surface(std::array<float, 2> uv0, std::array<float, 2> uv1, Float3 vertexColor,
                     const UvFootprint& footprint = {}) const;

  static PbrTexture MakeTexture(const std::optional<TextureSlot>& slot, TextureImage::Encoding encoding,
                                const TextureLoader& load);

  static constexpr float kMirrorRoughness = static_cast<float>(MetallicRoughness::kMirrorRoughness);

 private:
  void LoadLitTextures(const MetallicRoughness& m, const TextureLoader& load);

  bool textured_ = false;                     // it holds at least one loaded texture
  bool readsTexCoord_[2] = {false, false};  // some texture of the material reads TEXCOORD_0, _1
};

}  // namespace tcfarm
