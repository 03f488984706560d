// glTF's metallic-roughness model's shading (proto/scene/material.h, MetallicRoughness):
// its factors and textures (PbrMaterial, gltf_material.h) read at a hit with their
// footprint, normal maps and their tangent frames, glTF's BRDF (gltf_brdf.h) for each
// light, and its ray tree (mirror, transmission, coat, blending). Its per-hit parts are
// calls into metallic_roughness.cpp: their work dwarfs a call, and inlined they would
// swell the tracer's loops for every other model.
#pragma once

#include <memory>

#include "proto/scene/scene.h"
#include "worker/embree/surface_filter.h"
#include "worker/trace/float3.h"
#include "worker/trace/materials/gltf_brdf.h"
#include "worker/trace/materials/gltf_material.h"
#include "worker/trace/textures.h"

namespace tcfarm {

struct MetallicRoughnessShading {
  using Surface = PbrSurface;
  PbrMaterial gltf;

  // Only the images of a material some shape uses (`used`) are decoded.
  MetallicRoughnessShading(const MetallicRoughness& m, const TextureLoader& load, bool used);
  // Alpha masks and blending, and one-sided surfaces, as Embree filters (gltf_surface_rule.h).
  static std::unique_ptr<SurfaceRule> SurfaceRuleFor(const Shape& shape, const MetallicRoughness& m,
                                                     const ShapeUvSets& uvs, const TextureLoader& load);

  bool ReadsTexCoord(int set) const { return gltf.ReadsTexCoord(set); }
  bool ReadsTangents() const { return static_cast<bool>(gltf.normalTexture); }
  bool ReadsTriangles() const { return true; }  // its inputs are read at every hit
  template <typename ShapeShading>
  bool VariesOver(const ShapeShading&) const { return true; }
  bool Unlit() const { return gltf.unlit; }
  bool Blends() const { return gltf.blends; }
  float Coverage(const Surface& s) const { return s.alpha; }
  bool MirrorsOrRefracts() const { return gltf.MayContinue(); }

  // The BRDF's inputs at the hit, and its normal as the normal map tilts it.
  template <typename Tracer>
  void Shade(const Tracer& tracer, const typename Tracer::ShapeShading& shape, const typename Tracer::RawHit& raw,
             typename Tracer::SurfaceHit& hit) const;
  // A uniform sky of radiance `ambient` reflected, and the surface's emission.
  Float3 Ambient(const Surface& s, Float3 arriving, float ambient) const;
  Float3 Reflected(const Surface& s, Float3 towardLight, Float3 normal, Float3 arriving) const;
  template <typename Tracer>
  Float3 Combine(Tracer& tracer, const typename Tracer::SurfaceHit& hit, const Surface& s, Float3 local,
                 int depth) const;
};

}  // namespace tcfarm
