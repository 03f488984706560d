// Files real exporters wrote, or broke, as tests/gltf/test_assimp_models.py found them in
// Debian's assimp-testmodels, each made here in its smallest form: a glTF 1.0 file is
// refused as one, a default scene that does not exist is refused, a TRIANGLES primitive
// whose count is not a multiple of 3 is drawn without its leftover and says so, and a file
// that draws nothing says so.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "proto/scene/import/scene_import.h"
#include "tests/support/cpp/scene_test_support.h"

namespace tcfarm {
namespace {

using nlohmann::json;

std::string Floats(const std::vector<float>& values) {
  return std::string(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(float));
}

// One node drawing `vertices` positions (a fan of triangles in z = 0) as TRIANGLES, without
// indices; `indices`, when given, are added as unsigned bytes after the positions.
json Triangles(size_t vertices, const std::vector<uint8_t>& indices = {}) {
  std::vector<float> positions;
  for (size_t v = 0; v < vertices; ++v) {
    positions.insert(positions.end(), {static_cast<float>(v % 2), static_cast<float>(v / 2), 0});
  }
  const std::string data = Floats(positions) + std::string(indices.begin(), indices.end());
  json primitive = {{"attributes", {{"POSITION", 0}}}};
  json views = {{{"buffer", 0}, {"byteLength", 12 * vertices}}};
  json accessors = {{{"bufferView", 0}, {"componentType", 5126}, {"type", "VEC3"}, {"count", vertices}}};
  if (!indices.empty()) {
    primitive["indices"] = 1;
    views.push_back({{"buffer", 0}, {"byteOffset", 12 * vertices}, {"byteLength", indices.size()}});
    accessors.push_back({{"bufferView", 1}, {"componentType", 5121}, {"type", "SCALAR"}, {"count", indices.size()}});
  }
  return {{"asset", {{"version", "2.0"}}},
          {"scene", 0},
          {"scenes", {{{"nodes", {0}}}}},
          {"nodes", {{{"mesh", 0}}}},
          {"meshes", {{{"primitives", {primitive}}}}},
          {"buffers", {{{"byteLength", data.size()}, {"uri", "data:application/octet-stream;base64," + Base64(data)}}}},
          {"bufferViews", views},
          {"accessors", accessors}};
}

std::string ImportError(const json& gltf) {
  return ErrorOf([&] { ImportSceneBytes(gltf.dump(), "gltf"); });
}

std::vector<ImportWarning> WarningsOf(const Scene& scene, const std::string& code) {
  std::vector<ImportWarning> found;
  for (const ImportWarning& warning : scene.importWarnings) {
    if (warning.code == code) found.push_back(warning);
  }
  return found;
}

// Found by tests/fuzz/gltf_fuzz: a number past a double's range made the parser throw an
// exception that is no parse_error, and the importer let it end the process.
TEST(GltfDocumentTest, ANumberPastADoublesRangeIsRefused) {
  const std::string what =
      ErrorOf([] { ImportSceneBytes(R"({"asset": {"version": "2.0"}, "extras": 1.2e308668930054})", "gltf"); });
  EXPECT_NE(what.find("the JSON does not parse: number overflow parsing '1.2e308668930054'"), std::string::npos)
      << what;
}

TEST(GltfDocumentTest, AGltf1FileIsRefusedAsOne) {
  // glTF 1.0 named its default scene by a string and kept its collections in objects.
  json gltf = {{"asset", {{"version", "1.0"}}},
               {"scene", "defaultScene"},
               {"scenes", {{"defaultScene", {{"nodes", json::array()}}}}}};
  EXPECT_EQ(ImportError(gltf),
            "scene/asset/version: the gltf scene: version \"1.0\": a glTF 1.0 file, which this importer does not "
            "read; expected a glTF 2.0 file (asset.version \"2.0\")");
  gltf["asset"]["version"] = 1;  // as some 1.0 exporters wrote it
  EXPECT_NE(ImportError(gltf).find("version 1: a glTF 1.0 file"), std::string::npos) << ImportError(gltf);
}

TEST(GltfDocumentTest, OnlyVersion2IsRead) {
  json gltf = Triangles(3);
  gltf["asset"]["version"] = "2.1";  // a later minor version is read as 2.0 (its minVersion would say otherwise)
  EXPECT_EQ(ImportSceneBytes(gltf.dump(), "gltf").shapes.size(), 1u);
  gltf["asset"]["version"] = "3.0";
  EXPECT_EQ(ImportError(gltf),
            "scene/asset/version: the gltf scene: version \"3.0\"; expected a glTF 2.0 file (asset.version \"2.0\")");
  gltf["asset"].erase("version");
  EXPECT_EQ(ImportError(gltf),
            "scene/asset: the gltf scene: no asset.version; expected a glTF 2.0 file (asset.version \"2.0\")");
  gltf.erase("asset");
  EXPECT_EQ(ImportError(gltf),
            "scene: the gltf scene: no \"asset\" property; expected a glTF 2.0 file (asset.version \"2.0\")");
  EXPECT_EQ(ImportError(json::object()), ImportError(gltf));  // not "JSON string too short", as tinygltf says
}

TEST(GltfDocumentTest, ADefaultSceneMustExistEvenWithoutScenes) {
  json gltf = Triangles(3);
  gltf.erase("scenes");
  EXPECT_EQ(ImportError(gltf),
            "scene/scene: the gltf scene: scene 0 does not exist (the file has 0 scenes); expected the index of a "
            "scene");
  gltf.erase("scene");  // no scene at all: every root node is drawn
  EXPECT_EQ(ImportSceneBytes(gltf.dump(), "gltf").shapes.size(), 1u);
}

TEST(GltfDocumentTest, LeftoverVerticesOfTrianglesAreLeftOutAndSaid) {
  const Scene whole = ImportSceneBytes(Triangles(6).dump(), "gltf");
  EXPECT_TRUE(WarningsOf(whole, "incomplete_triangle").empty());
  const Scene leftover = ImportSceneBytes(Triangles(5).dump(), "gltf");
  ASSERT_EQ(leftover.shapes.size(), 1u);
  EXPECT_EQ(leftover.shapes[0].Mesh().triangles.size(), 1u);
  const std::vector<ImportWarning> warnings = WarningsOf(leftover, "incomplete_triangle");
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_EQ(warnings[0].pointer, "/meshes/0/primitives/0");
  EXPECT_EQ(warnings[0].message, "5 vertices are not whole triangles; the last two are left out");
}

TEST(GltfDocumentTest, LeftoverIndicesOfTrianglesAreLeftOutAndSaid) {
  const Scene scene = ImportSceneBytes(Triangles(4, {0, 1, 2, 1, 3, 2, 0}).dump(), "gltf");
  ASSERT_EQ(scene.shapes.size(), 1u);
  EXPECT_EQ(scene.shapes[0].Mesh().triangles.size(), 2u);
  const std::vector<ImportWarning> warnings = WarningsOf(scene, "incomplete_triangle");
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_EQ(warnings[0].message, "7 indices are not whole triangles; the last one is left out");
}

TEST(GltfDocumentTest, AFileThatDrawsNothingSaysSo) {
  EXPECT_TRUE(WarningsOf(ImportSceneBytes(Triangles(3).dump(), "gltf"), "empty_scene").empty());
  json emptyScene = {{"asset", {{"version", "2.0"}}}, {"scene", 0}, {"scenes", {json::object()}}};
  const std::vector<ImportWarning> empty = WarningsOf(ImportSceneBytes(emptyScene.dump(), "gltf"), "empty_scene");
  ASSERT_EQ(empty.size(), 1u);
  EXPECT_EQ(empty[0].pointer, "/scenes/0");
  EXPECT_EQ(empty[0].message, "no node of the scene draws a triangle; the frames show only the background");
  json points = Triangles(3);
  points["meshes"][0]["primitives"][0]["mode"] = 0;
  points.erase("scenes");
  points.erase("scene");
  const std::vector<ImportWarning> pointsOnly = WarningsOf(ImportSceneBytes(points.dump(), "gltf"), "empty_scene");
  ASSERT_EQ(pointsOnly.size(), 1u);
  EXPECT_EQ(pointsOnly[0].pointer, "/nodes");
}

}  // namespace
}  // namespace tcfarm
