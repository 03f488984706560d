// Materials: how a surface answers light. Each model is a struct of its parameters here,
// named once in TCFARM_MATERIAL_MODELS below, and a Material holds one of them:
//
// - Phong (the Whitted model of the paper's scenes): diffuse and specular colours, a Phong
//   exponent, mirror reflection and refraction weights. Every scene written in tcfarm's own
//   format without a "pbr" block uses it.
// - MetallicRoughness (glTF 2.0's material model, its Appendix B BRDF): base colour,
//   metallic and roughness factors and textures, normal, occlusion and emissive maps, alpha,
//   and the KHR_materials extensions tcfarm implements. glTF and a "pbr" block use it.
//
// Each model answers the same few questions (Reflects, Refracts, Blends, ReadsTexCoord,
// ReadsTangents, ForEachTexture), so that nothing outside its own files asks which model a
// material has. Its reading and writing live in proto/scene/materials/<stem>.cpp, its
// shading in worker/trace/materials/<stem>.h.
#pragma once

#include <array>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <variant>

#include "proto/scene/transform.h"

namespace tcfarm {

// An image that colours a surface through the mesh's texture coordinates (u to the right,
// v down, as glTF has them).
//
// The image comes from exactly one of two places: `image`, a file in the scene's folder
// (a scene read from disk), or `asset`, the SHA-256 of the image file's bytes, which the
// farm's workers fetch by hash (a scene submitted over the network names its images so,
// and its own hash then covers them).
struct Texture {
  enum class Wrap { kRepeat, kClampToEdge, kMirroredRepeat };
  enum class Filter { kLinear, kNearest };
  std::string image;  // as the scene names it, relative to its folder
  std::string asset;  // 64 lowercase hex
  // Where the bytes are now (neither is written out): a file (inside the scene's folder, or
  // in a worker's asset cache), or memory (an image embedded in a glTF file, whose hash
  // `asset` then holds).
  std::filesystem::path file;
  std::shared_ptr<const std::string> bytes;
  Wrap wrapS = Wrap::kRepeat, wrapT = Wrap::kRepeat;
  Filter filter = Filter::kLinear;  // magnifying
  // Minified (glTF materials only): filtered over the image's mip levels, or the full image
  // alone (a glTF sampler whose minFilter is NEAREST or LINEAR asks for that).
  bool mipmaps = true;

  // For messages: the file the scene names, or the asset's hash.
  std::string Describe() const { return image.empty() ? "asset " + asset : image; }
};

// Where a texture is read from a surface: which texture coordinates, moved how
// (KHR_texture_transform: uv' = T(offset) R(rotation) S(scale) uv).
struct TextureSlot {
  Texture texture;
  int texCoord = 0;  // TEXCOORD_0 or TEXCOORD_1
  std::array<double, 2> offset{0, 0}, scale{1, 1};
  double rotation = 0;  // radians, counter-clockwise in uv
  // normal maps: the scale of the map's x and y; occlusion maps: its strength
  double amount = 1;

  bool Transformed() const { return offset != std::array<double, 2>{0, 0} || scale != std::array<double, 2>{1, 1} || rotation != 0; }
};

// The Whitted model's parameters.
struct Phong {
  Vec3 diffuse{0.8, 0.8, 0.8};
  Vec3 specular{0, 0, 0};
  double shininess = 32;      // Phong exponent
  double reflectivity = 0;    // 0..1, mirror reflection weight
  double transparency = 0;    // 0..1, refraction weight
  double indexOfRefraction = 1.5;
  // Linear RGB the surface shows of itself, whatever lights it: it lights nothing else.
  Vec3 emission{0, 0, 0};
  // Multiplies `diffuse` where the mesh has texture coordinates; its colours are sRGB-encoded.
  std::optional<Texture> diffuseTexture;

  bool ReadsTexCoord(int set) const { return set == 0 && diffuseTexture.has_value(); }
  bool ReadsTangents() const { return false; }
  bool Reflects() const { return reflectivity > 0; }
  bool Refracts() const { return transparency > 0; }
  bool Blends() const { return false; }
  template <typename Self, typename Visit>
  static void ForEachTexture(Self& self, Visit visit) {
    if (self.diffuseTexture) visit(*self.diffuseTexture, std::string("diffuse_texture"));
  }
};

// glTF's metallic-roughness model. Colour factors are linear; colour textures (base colour,
// emissive) are sRGB-encoded, the others linear, as glTF has them.
struct MetallicRoughness {
  enum class Alpha { kOpaque, kMask, kBlend };
  Vec3 baseColor{1, 1, 1};
  double alpha = 1;           // base colour's alpha factor
  double metallic = 1, roughness = 1;
  std::optional<TextureSlot> baseColorTexture;
  std::optional<TextureSlot> metallicRoughnessTexture;  // B: metallic, G: roughness
  std::optional<TextureSlot> normalTexture;             // tangent space; amount: its scale
  std::optional<TextureSlot> occlusionTexture;          // R; amount: its strength
  std::optional<TextureSlot> emissiveTexture;
  Vec3 emissive{0, 0, 0};
  double emissiveStrength = 1;  // KHR_materials_emissive_strength
  Alpha alphaMode = Alpha::kOpaque;
  double alphaCutoff = 0.5;
  bool doubleSided = false;
  bool unlit = false;           // KHR_materials_unlit: the base colour, whatever lights it
  double ior = 1.5;             // KHR_materials_ior: f0 = ((ior - 1) / (ior + 1))^2
  double transmission = 0;      // KHR_materials_transmission
  double specular = 1;          // KHR_materials_specular: the dielectric f0's weight
  Vec3 specularColor{1, 1, 1};  // and its colour
  // KHR_materials_clearcoat: a smooth dielectric layer (f0 0.04) over the rest, with its own
  // roughness and normal map. 0: no coat (the textures then change nothing).
  double clearcoat = 0, clearcoatRoughness = 0;
  std::optional<TextureSlot> clearcoatTexture;           // R, times clearcoat
  std::optional<TextureSlot> clearcoatRoughnessTexture;  // G, times clearcoatRoughness
  std::optional<TextureSlot> clearcoatNormalTexture;     // tangent space; amount: its scale

  // Whether a "pbr" block says anything of a coat (written out only then).
  bool MentionsClearcoat() const {
    return clearcoat > 0 || clearcoatTexture || clearcoatRoughnessTexture || clearcoatNormalTexture;
  }
  // Each texture slot it may fill, with its key in a material's "pbr" block: the one list
  // of them that reading, writing, fetching and shading walk.
  template <typename Self, typename Visit>
  static void ForEachSlot(Self& self, Visit visit) {
    visit(self.baseColorTexture, "base_color_texture");
    visit(self.metallicRoughnessTexture, "metallic_roughness_texture");
    visit(self.normalTexture, "normal_texture");
    visit(self.occlusionTexture, "occlusion_texture");
    visit(self.emissiveTexture, "emissive_texture");
    visit(self.clearcoatTexture, "clearcoat_texture");
    visit(self.clearcoatRoughnessTexture, "clearcoat_roughness_texture");
    visit(self.clearcoatNormalTexture, "clearcoat_normal_texture");
  }
  bool ReadsTexCoord(int set) const {
    bool reads = false;
    ForEachSlot(*this, [&](const std::optional<TextureSlot>& slot, const char*) {
      reads = reads || (slot && slot->texCoord == set);
    });
    return reads;
  }
  bool ReadsTangents() const { return normalTexture.has_value(); }
  bool Reflects() const {
    if (unlit) return false;
    const bool smoothCoat =
        clearcoat > 0 && (clearcoatRoughness < kMirrorRoughness || clearcoatRoughnessTexture.has_value());
    return roughness < kMirrorRoughness || metallicRoughnessTexture.has_value() || smoothCoat;
  }
  bool Refracts() const { return alphaMode == Alpha::kBlend || (!unlit && transmission > 0 && metallic < 1); }
  bool Blends() const { return alphaMode == Alpha::kBlend; }
  template <typename Self, typename Visit>
  static void ForEachTexture(Self& self, Visit visit) {
    ForEachSlot(self, [&](auto& slot, const char* key) {
      if (slot) visit(slot->texture, "pbr/" + std::string(key));
    });
  }

  // A surface smoother than this traces its mirror ray (weighted by Fresnel), as
  // Whitted's mirrors do; a rougher one reflects lights only, through its GGX lobe.
  static constexpr double kMirrorRoughness = 0.25;
};

// Every material model, each named once, in the order of Material::model's alternatives
// (the first is a material's default): X(Stem) gives the parameters' struct <Stem> above,
// the scene format's <Stem>MaterialFormat() (proto/scene/materials/<stem>.cpp: reading,
// writing, checking it) and the worker's <Stem>Shading (worker/trace/materials/<stem>.h).
// A model missing any part fails to compile or link.
#define TCFARM_MATERIAL_MODELS(X) X(Phong) X(MetallicRoughness)

// A std::variant of the models in the list's order (the first, ignored argument takes the
// list's leading comma).
template <typename Ignored, typename... Models>
using VariantOfModels = std::variant<Models...>;
#define TCFARM_MATERIAL_MODEL_TYPE(Stem) , Stem
using AnyMaterialModel = VariantOfModels<void TCFARM_MATERIAL_MODELS(TCFARM_MATERIAL_MODEL_TYPE)>;
#undef TCFARM_MATERIAL_MODEL_TYPE

struct Material {
  std::string name;
  AnyMaterialModel model;  // Phong's defaults unless set

  // The model's parameters, or null when the material has another model.
  template <typename Model>
  Model* If() { return std::get_if<Model>(&model); }
  template <typename Model>
  const Model* If() const { return std::get_if<Model>(&model); }
  template <typename Model>
  bool Is() const { return std::holds_alternative<Model>(model); }
  // The model's parameters; throws std::bad_variant_access for another model.
  template <typename Model>
  Model& As() { return std::get<Model>(model); }
  template <typename Model>
  const Model& As() const { return std::get<Model>(model); }

  // Each texture the material reads, with its path in the material's JSON ("diffuse_texture",
  // "pbr/normal_texture"): whoever fetches, binds or lists images asks here.
  template <typename Visit>
  void ForEachTexture(Visit visit) {
    std::visit([&](auto& m) { m.ForEachTexture(m, visit); }, model);
  }
  template <typename Visit>
  void ForEachTexture(Visit visit) const {
    std::visit([&](const auto& m) { m.ForEachTexture(m, visit); }, model);
  }
  bool Reflects() const { return std::visit([](const auto& m) { return m.Reflects(); }, model); }
  // Whether rays continue through it: refracted, or straight on past a blended surface.
  bool Refracts() const { return std::visit([](const auto& m) { return m.Refracts(); }, model); }
  // Whether shadow rays pass it, weighed by its coverage (glTF's alphaMode BLEND).
  bool Blends() const { return std::visit([](const auto& m) { return m.Blends(); }, model); }
  // Whether it reads a mesh's texture coordinates `set` (0 or 1), or its tangents.
  bool ReadsTexCoord(int set) const { return std::visit([&](const auto& m) { return m.ReadsTexCoord(set); }, model); }
  bool ReadsTangents() const { return std::visit([](const auto& m) { return m.ReadsTangents(); }, model); }
};

}  // namespace tcfarm
