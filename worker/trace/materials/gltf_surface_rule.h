// glTF's alphaMode MASK and BLEND and doubleSided false as a shape's surface rule
// (embree/surface_filter.h): a hit counts where the base colour's alpha (factor times
// texture) reaches the material's cutoff, and, for a one-sided material, only on the
// triangle's front. A blended surface lets every shadow ray through: the tracer weighs the
// light by 1 - alpha of each blended surface on its way, front to back.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "proto/scene/scene.h"
#include "worker/embree/surface_filter.h"
#include "worker/trace/materials/gltf_material.h"

namespace tcfarm {

class GltfSurfaceRule : public SurfaceRule {
 public:
  // The rule of a shape's material, or null when every hit of it counts (opaque or
  // blended and double-sided, or a shape that is not a triangle mesh).
  static std::unique_ptr<SurfaceRule> For(const Shape& shape, const MetallicRoughness& m, const ShapeUvSets& uvs,
                                          const TextureLoader& load);

  bool Keeps(unsigned primitive, float u, float v, bool backFace, bool occlusion) const override;

 private:
  GltfSurfaceRule() = default;
  float AlphaAt(unsigned primitive, float u, float v) const;

  bool cullBackFaces_ = false;
  bool masks_ = false;
  bool blends_ = false;  // shadow rays pass; the tracer weighs them by 1 - alpha
  float cutoff_ = 0.5f, alpha_ = 1;
  PbrTexture texture_;  // the base colour texture, for its alpha
  const std::array<uint32_t, 3>* triangles_ = nullptr;
  ShapeUvSets::value_type uvs_;  // the texture's coordinates, by vertex
};

}  // namespace tcfarm
