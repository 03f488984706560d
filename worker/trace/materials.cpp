#include "worker/trace/materials.h"

namespace tcfarm {
namespace {

// The shading struct of each model's parameters: <Stem> to <Stem>Shading.
template <typename Model>
struct ShadingOf;
#define TCFARM_SHADING_OF(Stem)     \
  template <>                       \
  struct ShadingOf<Stem> {          \
    using Type = Stem##Shading;     \
  };
TCFARM_MATERIAL_MODELS(TCFARM_SHADING_OF)
#undef TCFARM_SHADING_OF

template <typename Params>
using ShadingType = typename ShadingOf<std::decay_t<Params>>::Type;

}  // namespace

std::vector<ShadingMaterial> MakeMaterials(const Scene& scene, const TextureLoader& load) {
  std::vector<bool> used(scene.materials.size(), false);
  for (const Shape& shape : scene.shapes) used[static_cast<size_t>(shape.material)] = true;
  std::vector<ShadingMaterial> materials;
  for (size_t i = 0; i < scene.materials.size(); ++i) {
    materials.push_back(std::visit(
        [&](const auto& params) -> ShadingMaterial { return ShadingType<decltype(params)>(params, load, used[i]); },
        scene.materials[i].model));
  }
  return materials;
}

std::unique_ptr<SurfaceRule> MakeSurfaceRule(const Shape& shape, const Material& material, const ShapeUvSets& uvs,
                                             const TextureLoader& load) {
  return std::visit(
      [&](const auto& params) { return ShadingType<decltype(params)>::SurfaceRuleFor(shape, params, uvs, load); },
      material.model);
}

}  // namespace tcfarm
