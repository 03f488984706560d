// glTF's metallic-roughness model: a material's "pbr" block (proto/scene.md, "Materials"),
// its texture slots and KHR_materials extensions.
#include "proto/scene/materials/material_format.h"
#include "proto/scene/parse/scene_reader.h"
#include "proto/scene/scene_write.h"

namespace tcfarm {
namespace {

using namespace scene_parse;
using scene_write::TextureJson;
using scene_write::Vec3Json;

bool ReadBool(const Node& node, const std::string& expected) {
  if (!node.value.is_boolean()) FailType(node, expected);
  return node.value.get<bool>();
}

std::array<double, 2> ReadPair(const Node& node, const std::string& expected) {
  ExpectArray(node, 2, expected);
  return {ReadNumber(node.Element(0), expected), ReadNumber(node.Element(1), expected)};
}

MetallicRoughness::Alpha ReadAlphaMode(const Node& node) {
  const std::string expected = "\"opaque\", \"mask\" or \"blend\"";
  const std::string name = ReadString(node, expected);
  if (name == "opaque") return MetallicRoughness::Alpha::kOpaque;
  if (name == "mask") return MetallicRoughness::Alpha::kMask;
  if (name == "blend") return MetallicRoughness::Alpha::kBlend;
  Fail(node.pointer, "unknown alpha mode " + Quote(name), expected);
}

// A texture with its texture coordinates and their transform; `amountKey` names the
// slot's own number (a normal map's "scale", an occlusion map's "strength"), if any.
TextureSlot ReadTextureSlot(SceneReader& reader, const Node& node, const std::string& amountKey = "") {
  std::vector<std::string> keys{"tex_coord", "uv_offset", "uv_scale", "uv_rotation"};
  if (!amountKey.empty()) keys.push_back(amountKey);
  TextureSlot slot;
  slot.texture = reader.ReadTexture(node, keys);
  if (node.Has("tex_coord")) slot.texCoord = ReadInt(node.Member("tex_coord"), 0, 1);
  if (node.Has("uv_offset")) slot.offset = ReadPair(node.Member("uv_offset"), "an offset [u, v] of finite numbers");
  if (node.Has("uv_scale")) slot.scale = ReadPair(node.Member("uv_scale"), "a scale [u, v] of finite numbers");
  if (node.Has("uv_rotation")) slot.rotation = ReadNumber(node.Member("uv_rotation"), "a rotation in radians");
  if (!amountKey.empty() && node.Has(amountKey)) {
    slot.amount = amountKey == "strength"
                      ? ReadInRange(node.Member(amountKey), 0, 1, "an occlusion strength in [0, 1]")
                      : ReadInRange(node.Member(amountKey), -scene_limits::kMaxNormalScale,
                                    scene_limits::kMaxNormalScale, "a normal scale, a finite number");
  }
  return slot;
}

// KHR_materials_clearcoat's keys.
void ReadClearcoat(SceneReader& reader, const Node& node, MetallicRoughness& m) {
  const std::string unit = "a number in [0, 1]";
  if (node.Has("clearcoat")) m.clearcoat = ReadInRange(node.Member("clearcoat"), 0, 1, unit);
  if (node.Has("clearcoat_roughness")) m.clearcoatRoughness = ReadInRange(node.Member("clearcoat_roughness"), 0, 1, unit);
  if (node.Has("clearcoat_texture")) m.clearcoatTexture = ReadTextureSlot(reader, node.Member("clearcoat_texture"));
  if (node.Has("clearcoat_roughness_texture")) {
    m.clearcoatRoughnessTexture = ReadTextureSlot(reader, node.Member("clearcoat_roughness_texture"));
  }
  if (node.Has("clearcoat_normal_texture")) {
    m.clearcoatNormalTexture = ReadTextureSlot(reader, node.Member("clearcoat_normal_texture"), "scale");
  }
}

MetallicRoughness ReadPbr(SceneReader& reader, const Node& node) {
  ExpectObject(node,
               {"base_color", "alpha", "metallic", "roughness", "base_color_texture", "metallic_roughness_texture",
                "normal_texture", "occlusion_texture", "emissive", "emissive_strength", "emissive_texture",
                "alpha_mode", "alpha_cutoff", "double_sided", "unlit", "ior", "transmission", "specular",
                "specular_color", "clearcoat", "clearcoat_roughness", "clearcoat_texture",
                "clearcoat_roughness_texture", "clearcoat_normal_texture"},
               "a metallic-roughness material");
  const std::string unit = "a number in [0, 1]";
  MetallicRoughness m;
  if (node.Has("base_color")) m.baseColor = ReadColour(node.Member("base_color"));
  if (node.Has("alpha")) m.alpha = ReadInRange(node.Member("alpha"), 0, 1, unit);
  if (node.Has("metallic")) m.metallic = ReadInRange(node.Member("metallic"), 0, 1, unit);
  if (node.Has("roughness")) m.roughness = ReadInRange(node.Member("roughness"), 0, 1, unit);
  if (node.Has("base_color_texture")) m.baseColorTexture = ReadTextureSlot(reader, node.Member("base_color_texture"));
  if (node.Has("metallic_roughness_texture")) {
    m.metallicRoughnessTexture = ReadTextureSlot(reader, node.Member("metallic_roughness_texture"));
  }
  if (node.Has("normal_texture")) m.normalTexture = ReadTextureSlot(reader, node.Member("normal_texture"), "scale");
  if (node.Has("occlusion_texture")) m.occlusionTexture = ReadTextureSlot(reader, node.Member("occlusion_texture"), "strength");
  if (node.Has("emissive")) m.emissive = ReadColour(node.Member("emissive"));
  if (node.Has("emissive_strength")) {
    m.emissiveStrength = ReadInRange(node.Member("emissive_strength"), 0, scene_limits::kMaxEmissiveStrength,
                                     "a non-negative emissive strength");
  }
  if (node.Has("emissive_texture")) m.emissiveTexture = ReadTextureSlot(reader, node.Member("emissive_texture"));
  if (node.Has("alpha_mode")) m.alphaMode = ReadAlphaMode(node.Member("alpha_mode"));
  if (node.Has("alpha_cutoff")) m.alphaCutoff = ReadInRange(node.Member("alpha_cutoff"), 0, 1, unit);
  if (node.Has("double_sided")) m.doubleSided = ReadBool(node.Member("double_sided"), "true or false");
  if (node.Has("unlit")) m.unlit = ReadBool(node.Member("unlit"), "true or false");
  if (node.Has("ior")) {
    m.ior = ReadInRange(node.Member("ior"), scene_limits::kMinIndexOfRefraction, scene_limits::kMaxIndexOfRefraction,
                        "an index of refraction in [1, 10]");
  }
  if (node.Has("transmission")) m.transmission = ReadInRange(node.Member("transmission"), 0, 1, unit);
  if (node.Has("specular")) m.specular = ReadInRange(node.Member("specular"), 0, 1, unit);
  if (node.Has("specular_color")) m.specularColor = ReadColour(node.Member("specular_color"));
  ReadClearcoat(reader, node, m);
  return m;
}

nlohmann::json TextureSlotJson(const TextureSlot& slot, const char* amountKey = nullptr) {
  nlohmann::json result = TextureJson(slot.texture);
  result["tex_coord"] = slot.texCoord;
  if (slot.Transformed()) {
    result["uv_offset"] = nlohmann::json::array({slot.offset[0], slot.offset[1]});
    result["uv_scale"] = nlohmann::json::array({slot.scale[0], slot.scale[1]});
    result["uv_rotation"] = slot.rotation;
  }
  if (amountKey) result[amountKey] = slot.amount;
  return result;
}

nlohmann::json PbrJson(const MetallicRoughness& m) {
  static const char* const kAlphaModes[] = {"opaque", "mask", "blend"};
  nlohmann::json result{{"base_color", Vec3Json(m.baseColor)},
              {"alpha", m.alpha},
              {"metallic", m.metallic},
              {"roughness", m.roughness},
              {"emissive", Vec3Json(m.emissive)},
              {"emissive_strength", m.emissiveStrength},
              {"alpha_mode", kAlphaModes[static_cast<int>(m.alphaMode)]},
              {"alpha_cutoff", m.alphaCutoff},
              {"double_sided", m.doubleSided},
              {"unlit", m.unlit},
              {"ior", m.ior},
              {"transmission", m.transmission},
              {"specular", m.specular},
              {"specular_color", Vec3Json(m.specularColor)}};
  if (m.baseColorTexture) result["base_color_texture"] = TextureSlotJson(*m.baseColorTexture);
  if (m.metallicRoughnessTexture) result["metallic_roughness_texture"] = TextureSlotJson(*m.metallicRoughnessTexture);
  if (m.normalTexture) result["normal_texture"] = TextureSlotJson(*m.normalTexture, "scale");
  if (m.occlusionTexture) result["occlusion_texture"] = TextureSlotJson(*m.occlusionTexture, "strength");
  if (m.emissiveTexture) result["emissive_texture"] = TextureSlotJson(*m.emissiveTexture);
  // Only a coated material names the coat: scenes without one keep their text (and hash).
  if (m.MentionsClearcoat()) {
    result["clearcoat"] = m.clearcoat;
    result["clearcoat_roughness"] = m.clearcoatRoughness;
  }
  if (m.clearcoatTexture) result["clearcoat_texture"] = TextureSlotJson(*m.clearcoatTexture);
  if (m.clearcoatRoughnessTexture) {
    result["clearcoat_roughness_texture"] = TextureSlotJson(*m.clearcoatRoughnessTexture);
  }
  if (m.clearcoatNormalTexture) result["clearcoat_normal_texture"] = TextureSlotJson(*m.clearcoatNormalTexture, "scale");
  return result;
}

class MetallicRoughnessFormatImpl final : public MaterialFormat {
 public:
  const std::vector<std::string>& Keys() const override {
    static const std::vector<std::string> keys{"pbr"};
    return keys;
  }
  const char* OneKey() const override { return "a \"pbr\" block"; }
  const char* AllKeys() const override { return "one \"pbr\" block (glTF's metallic-roughness model)"; }

  void Read(SceneReader& reader, const Node& node, Material& material) const override {
    material.model = ReadPbr(reader, node.Member("pbr"));
  }
  nlohmann::json Write(const Material& material) const override {
    return nlohmann::json{{"pbr", PbrJson(material.As<MetallicRoughness>())}};
  }
};

}  // namespace

const MaterialFormat& MetallicRoughnessMaterialFormat() {
  static const MetallicRoughnessFormatImpl format;
  return format;
}

}  // namespace tcfarm
