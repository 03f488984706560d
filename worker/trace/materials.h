// Materials as shading sees them: one struct per model, <Stem>Shading in
// worker/trace/materials/<stem>.h, named by TCFARM_MATERIAL_MODELS (proto/scene/material.h)
// and held in a std::variant, so that every hit reaches its model's code inline, without a
// virtual call. Each model has
//   using Surface: what it reads of a surface at one hit (MaterialSurface holds one);
//   <Stem>Shading(const <Stem>& params, const TextureLoader& load, bool used): made once per
//     scene; `used`: some shape has the material;
//   static SurfaceRuleFor(shape, params, uvs, load): which hits of a shape count (null: all);
//   ReadsTexCoord(set), ReadsTangents(), ReadsTriangles(): what it reads of a mesh at a hit;
//   VariesOver(shape): whether its colour may vary over the shape (else a moving sphere's
//     unlit hit may keep its horizon: horizons.h);
//   Unlit(): it shows itself whatever lights it (no shadow rays); MirrorsOrRefracts();
//   Blends(), Coverage(surface): shadow rays pass it, weighed by 1 - coverage;
//   Shade(tracer, shape, raw, hit): the hit's Surface (and its shading normal, if it tilts it);
//   Ambient(surface, arriving, ambient): what it shows with no light;
//   Reflected(surface, towardLight, normal, arriving): light of unit intensity from a light;
//   Combine(tracer, hit, surface, local, depth): its local light with the rays it spawns.
// The tracer (pixel_tracer.h) asks each through WithModel alone.
#pragma once

#include <algorithm>
#include <memory>
#include <new>
#include <type_traits>
#include <variant>
#include <vector>

#include "proto/scene/scene.h"
#include "worker/trace/float3.h"
#include "worker/trace/materials/metallic_roughness.h"
#include "worker/trace/materials/phong.h"

namespace tcfarm {

// Fraction of a material's diffuse colour seen with no light at all, so surfaces in
// shadow keep their shape (Whitted's ambient term): the yardstick's (bare_embree_loop.h);
// the tracer takes RenderSettings::ambient.
constexpr float kAmbient = 0.05f;

#define TCFARM_MATERIAL_SHADING(Stem) , Stem##Shading
using ShadingMaterial = VariantOfModels<void TCFARM_MATERIAL_MODELS(TCFARM_MATERIAL_SHADING)>;
#undef TCFARM_MATERIAL_SHADING
// What a hit's material model reads of its surface (its Surface), as its Shade wrote it:
// storage for the largest of the models' Surfaces, not a std::variant, which GCC zeroes
// whole at every hit (a `rep stos` that cost Phong scenes 3-5 %). Which Surface it holds,
// the hit's material says; Surfaces are trivially copyable, so hits copy as bytes.
template <typename... Surfaces>
class SurfaceSlot {
 public:
  SurfaceSlot() {}  // left unwritten: the model's Shade writes it, nothing else reads it first
  template <typename Surface>
  SurfaceSlot& operator=(const Surface& surface) {
    static_assert((std::is_same_v<Surface, Surfaces> || ...), "a Surface of a listed model");
    static_assert(std::is_trivially_copyable_v<Surface> && std::is_trivially_destructible_v<Surface>);
    new (bytes_) Surface(surface);
    return *this;
  }
  template <typename Surface>
  const Surface& As() const {
    return *std::launder(reinterpret_cast<const Surface*>(bytes_));
  }

 private:
  alignas(Surfaces...) unsigned char bytes_[std::max({sizeof(Surfaces)...})];
};
// SurfaceSlot of the Surfaces listed after a first, ignored type (the model list's form).
template <typename Ignored, typename... Surfaces>
using SurfaceSlotOfModels = SurfaceSlot<Surfaces...>;
#define TCFARM_MATERIAL_SURFACE(Stem) , Stem##Shading::Surface
using MaterialSurface = SurfaceSlotOfModels<void TCFARM_MATERIAL_MODELS(TCFARM_MATERIAL_SURFACE)>;
#undef TCFARM_MATERIAL_SURFACE

// `visit` of a material's model's shading, inlined (std::visit over two or three
// alternatives compiles to a jump; an if-chain over the indices measured slower).
template <typename Visit>
decltype(auto) WithModel(const ShadingMaterial& material, Visit visit) {
  return std::visit(visit, material);
}
// A model's Surface in a hit's MaterialSurface (which the model's Shade wrote).
template <typename Model>
const typename Model::Surface& SurfaceOf(const Model&, const MaterialSurface& surface) {
  return surface.template As<typename Model::Surface>();
}

// `load` decodes the textures materials use.
std::vector<ShadingMaterial> MakeMaterials(const Scene& scene, const TextureLoader& load);

// Which hits of a shape count, as its material's model says; null: every hit.
std::unique_ptr<SurfaceRule> MakeSurfaceRule(const Shape& shape, const Material& material, const ShapeUvSets& uvs,
                                             const TextureLoader& load);

}  // namespace tcfarm
