// Phong's parameters: a material's "diffuse", "specular", "shininess", "reflectivity",
// "transparency", "ior", "diffuse_texture" and "emission" (proto/scene.md, "Materials").
#include "proto/scene/materials/material_format.h"
#include "proto/scene/parse/scene_reader.h"
#include "proto/scene/scene_write.h"

namespace tcfarm {
namespace {

using namespace scene_parse;
using scene_write::TextureJson;
using scene_write::Vec3Json;

// Reflection and refraction share the light that is not absorbed.
void CheckShares(const Node& node, const Phong& m) {
  if (m.reflectivity + m.transparency <= 1) return;
  Fail(node.MemberPointer(node.Has("transparency") ? "transparency" : "reflectivity"),
       "reflectivity " + FormatNumber(m.reflectivity) + " + transparency " + FormatNumber(m.transparency) +
           " exceeds 1",
       "reflectivity + transparency <= 1 (they share the light that is not absorbed)");
}

class PhongFormatImpl final : public MaterialFormat {
 public:
  const std::vector<std::string>& Keys() const override {
    static const std::vector<std::string> keys{"diffuse",      "specular", "shininess",       "reflectivity",
                                               "transparency", "ior",      "diffuse_texture", "emission"};
    return keys;
  }
  const char* OneKey() const override { return "a Phong parameter"; }
  const char* AllKeys() const override { return "Phong's parameters"; }

  void Read(SceneReader& reader, const Node& node, Material& material) const override {
    Phong m;
    if (node.Has("diffuse_texture")) m.diffuseTexture = reader.ReadTexture(node.Member("diffuse_texture"));
    if (node.Has("diffuse")) m.diffuse = ReadColour(node.Member("diffuse"));
    if (node.Has("emission")) m.emission = ReadColour(node.Member("emission"));
    if (node.Has("specular")) m.specular = ReadColour(node.Member("specular"));
    if (node.Has("shininess")) m.shininess = ReadNonNegative(node.Member("shininess"), "a non-negative Phong exponent");
    if (node.Has("reflectivity")) {
      m.reflectivity = ReadInRange(node.Member("reflectivity"), 0, 1, "a number in [0, 1]");
    }
    if (node.Has("transparency")) {
      m.transparency = ReadInRange(node.Member("transparency"), 0, 1, "a number in [0, 1]");
    }
    if (node.Has("ior")) m.indexOfRefraction = ReadInRange(node.Member("ior"), 1, 10, "an index of refraction in [1, 10]");
    CheckShares(node, m);
    material.model = std::move(m);
  }

  nlohmann::json Write(const Material& material) const override {
    const Phong& m = material.As<Phong>();
    nlohmann::json result{{"diffuse", Vec3Json(m.diffuse)},   {"specular", Vec3Json(m.specular)},
                          {"shininess", m.shininess},         {"reflectivity", m.reflectivity},
                          {"transparency", m.transparency}, {"ior", m.indexOfRefraction}};
    if (m.diffuseTexture) result["diffuse_texture"] = TextureJson(*m.diffuseTexture);
    if (m.emission != Vec3{}) result["emission"] = Vec3Json(m.emission);
    return result;
  }
};

}  // namespace

const MaterialFormat& PhongMaterialFormat() {
  static const PhongFormatImpl format;
  return format;
}

}  // namespace tcfarm
