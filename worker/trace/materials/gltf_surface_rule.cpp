#include "worker/trace/materials/gltf_surface_rule.h"

#include "worker/trace/barycentric.h"

namespace tcfarm {

std::unique_ptr<SurfaceRule> GltfSurfaceRule::For(const Shape& shape, const MetallicRoughness& m, const ShapeUvSets& uvs,
                                                  const TextureLoader& load) {
  if (shape.Mesh().triangles.empty()) return nullptr;
  const bool masks = m.alphaMode == MetallicRoughness::Alpha::kMask;
  const bool blends = m.alphaMode == MetallicRoughness::Alpha::kBlend;
  if (!masks && !blends && m.doubleSided) return nullptr;
  std::unique_ptr<GltfSurfaceRule> rule(new GltfSurfaceRule());
  rule->cullBackFaces_ = !m.doubleSided;
  rule->masks_ = masks;
  rule->blends_ = blends;
  rule->cutoff_ = static_cast<float>(m.alphaCutoff);
  rule->alpha_ = static_cast<float>(m.alpha);
  const TriangleMesh& mesh = shape.Mesh();
  rule->triangles_ = mesh.triangles.data();
  if (masks && m.baseColorTexture) {
    const ShapeUvSets::value_type& read = uvs[m.baseColorTexture->texCoord == 1];
    if (read && !read->empty()) {
      rule->texture_ = PbrMaterial::MakeTexture(m.baseColorTexture, TextureImage::Encoding::kSrgb, load);
      rule->uvs_ = read;
    }
  }
  return rule;
}

float GltfSurfaceRule::AlphaAt(unsigned primitive, float u, float v) const {
  if (!texture_) return alpha_;
  const std::array<float, 2> uv = AtBarycentric(uvs_->data(), triangles_[primitive], u, v);
  // At the full image (no mip level): Embree's filter callback knows the hit, not the ray's
  // footprint, and a shadow ray has none.
  return alpha_ * texture_.SampleAlpha(uv);
}

bool GltfSurfaceRule::Keeps(unsigned primitive, float u, float v, bool backFace, bool occlusion) const {
  if (occlusion && blends_) return false;
  if (cullBackFaces_ && backFace && !occlusion) return false;
  return !masks_ || AlphaAt(primitive, u, v) >= cutoff_;
}

}  // namespace tcfarm
