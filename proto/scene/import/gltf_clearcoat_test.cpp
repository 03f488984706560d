// KHR_materials_clearcoat as the glTF importer maps it, and optional extensions it does not
// implement, which it reports.
#include <gtest/gtest.h>

#include <string>

#include <nlohmann/json.hpp>

#include "proto/scene/import/scene_import.h"
#include "proto/scene/scene.h"

namespace tcfarm {
namespace {

using nlohmann::json;

// One triangle with a material and a 1 x 1 PNG texture, all in data URIs.
json TriangleWithMaterial(const json& material) {
  json document = json::parse(R"({
    "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
    "nodes": [{"mesh": 0}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "material": 0}]}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "type": "VEC3", "count": 3,
                   "min": [0, 0, 0], "max": [1, 1, 0]}],
    "bufferViews": [{"buffer": 0, "byteLength": 36}],
    "buffers": [{"byteLength": 36,
                 "uri": "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}],
    "images": [{"uri": "data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAIAAACQd1PeAAAADElEQVR4nGNoaPgPAAODAgAApfuJAAAAAElFTkSuQmCC"}],
    "textures": [{"source": 0}]})");
  document["materials"] = json::array({material});
  return document;
}

Scene Import(const json& document) { return ImportSceneBytes(document.dump(), "gltf"); }

TEST(GltfClearcoatTest, FactorsTexturesAndNormalScaleAreKept) {
  json document = TriangleWithMaterial(json::parse(R"({"name": "lacquer",
      "extensions": {"KHR_materials_clearcoat": {
        "clearcoatFactor": 0.75, "clearcoatRoughnessFactor": 0.25,
        "clearcoatTexture": {"index": 0},
        "clearcoatRoughnessTexture": {"index": 0, "texCoord": 1},
        "clearcoatNormalTexture": {"index": 0, "scale": 0.5,
                                   "extensions": {"KHR_texture_transform": {"offset": [0.5, 0]}}}}}})"));
  document["extensionsUsed"] = {"KHR_materials_clearcoat", "KHR_texture_transform"};
  const Scene scene = Import(document);
  // The triangle has no texture coordinates, no camera and no light, and the import says so.
  std::vector<std::string> codes;
  for (const ImportWarning& warning : scene.importWarnings) codes.push_back(warning.code);
  EXPECT_EQ(codes, (std::vector<std::string>{"texcoord_set_missing", "texcoord_set_missing", "default_camera",
                                             "default_light"}));
  ASSERT_EQ(scene.materials.size(), 2u);
  const MetallicRoughness& m = scene.materials[1].As<MetallicRoughness>();
  EXPECT_DOUBLE_EQ(m.clearcoat, 0.75);
  EXPECT_DOUBLE_EQ(m.clearcoatRoughness, 0.25);
  ASSERT_TRUE(m.clearcoatTexture && m.clearcoatRoughnessTexture && m.clearcoatNormalTexture);
  EXPECT_EQ(m.clearcoatRoughnessTexture->texCoord, 1);
  EXPECT_DOUBLE_EQ(m.clearcoatNormalTexture->amount, 0.5);
  EXPECT_DOUBLE_EQ(m.clearcoatNormalTexture->offset[0], 0.5);
  EXPECT_TRUE(scene.materials[1].Reflects());  // a smooth coat traces its mirror ray

  // What workers are given reads back as it was written, the coat's textures listed.
  const std::string written = SerializeScene(scene);
  EXPECT_EQ(SerializeScene(ParseScene(written)), written);
  const json pbr = json::parse(written)["materials"]["lacquer"]["pbr"];
  EXPECT_EQ(pbr["clearcoat"], 0.75);
  EXPECT_EQ(pbr["clearcoat_normal_texture"]["scale"], 0.5);
  EXPECT_EQ(pbr["clearcoat_roughness_texture"]["tex_coord"], 1);

  document["materials"][0]["extensions"]["KHR_materials_clearcoat"]["clearcoatFactor"] = 2;
  try {
    Import(document);
    FAIL() << "a clearcoat factor of 2 was taken";
  } catch (const SceneError& error) {
    EXPECT_EQ(error.pointer(), "/materials/0/extensions/KHR_materials_clearcoat/clearcoatFactor");
  }
}

TEST(GltfClearcoatTest, WithoutACoatNothingOfItIsWritten) {
  const Scene scene = Import(TriangleWithMaterial(json::parse(R"({"name": "plain"})")));
  EXPECT_FALSE(json::parse(SerializeScene(scene))["materials"]["plain"]["pbr"].contains("clearcoat"));
}

TEST(GltfClearcoatTest, OptionalExtensionsNotImplementedAreReportedWithTheirPointers) {
  json document = TriangleWithMaterial(json::parse(R"({"name": "m"})"));
  document["extensionsUsed"] = {"KHR_materials_clearcoat", "KHR_materials_sheen", "EXT_unknown"};
  const Scene scene = Import(document);
  std::vector<ImportWarning> extensions;
  for (const ImportWarning& warning : scene.importWarnings) {
    if (warning.code == "extension_not_implemented") extensions.push_back(warning);
  }
  ASSERT_EQ(extensions.size(), 2u);
  EXPECT_EQ(extensions[0].pointer, "/extensionsUsed/1");
  EXPECT_EQ(extensions[0].Line(),
            "the gltf scene at /extensionsUsed/1: extension \"KHR_materials_sheen\" is not implemented; "
            "what it adds is left out");
  EXPECT_EQ(extensions[1].pointer, "/extensionsUsed/2");
  EXPECT_NE(extensions[1].message.find("extension \"EXT_unknown\""), std::string::npos);
}

}  // namespace
}  // namespace tcfarm
