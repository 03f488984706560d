#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <unistd.h>

#include "tests/support/cpp/gltf_builder.h"
#include "tests/support/cpp/scene_test_support.h"
#include "proto/scene/import/importers.h"
#include "proto/scene/import/scene_import.h"
#include "tests/support/cpp/required_tool.h"

namespace tcfarm {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr double kPi = 3.14159265358979323846;
// Debian's assimp-testmodels (scripts/bootstrap installs it): read where it lies, never copied.
const fs::path kTestModels = "/usr/share/assimp/models/glTF2";



const std::vector<double> kTriangle = {0, 0, 0, 1, 0, 0, 0, 1, 0};

void ExpectNear(const Vec3& a, const Vec3& b, double tolerance = 1e-6) {
  EXPECT_NEAR(a.x, b.x, tolerance);
  EXPECT_NEAR(a.y, b.y, tolerance);
  EXPECT_NEAR(a.z, b.z, tolerance);
}

// What workers are given must read back as it was written.
void ExpectRoundTrip(const Scene& scene) {
  std::string written = SerializeScene(scene);
  EXPECT_EQ(SerializeScene(ParseScene(written)), written);
}

TEST(GltfImporterTest, StripsAndFansAsTheSpecNumbersThem) {
  using T = std::vector<std::array<uint32_t, 3>>;
  EXPECT_EQ(GltfTriangles({0, 1, 2, 3, 4}, 5), (T{{0, 1, 2}, {1, 3, 2}, {2, 3, 4}}));
  EXPECT_EQ(GltfTriangles({0, 1, 2, 3}, 6), (T{{1, 2, 0}, {2, 3, 0}}));
  EXPECT_EQ(GltfTriangles({0, 1, 2, 3, 4, 5, 6}, 4), (T{{0, 1, 2}, {3, 4, 5}}));
}

TEST(GltfImporterTest, StripPrimitiveBecomesItsTriangles) {
  GltfBuilder gltf;
  // A unit square as a strip of 4 vertices: two triangles facing +z.
  int mesh = gltf.Mesh({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0}, {}, 5);
  gltf.Node({{"mesh", mesh}}, true);
  Scene scene = gltf.Import();
  ASSERT_EQ(scene.shapes.size(), 1u);
  using T = std::vector<std::array<uint32_t, 3>>;
  EXPECT_EQ(scene.shapes[0].mesh.triangles, (T{{0, 1, 2}, {1, 3, 2}}));
  EXPECT_TRUE(scene.shapes[0].mesh.normals.empty());
  ExpectRoundTrip(scene);
}

// A child's world position through an animated, turned parent, in closed form.
TEST(GltfImporterTest, ChildIsCarriedByItsParents) {
  GltfBuilder gltf;
  int mesh = gltf.Mesh(kTriangle);
  // Grandparent: turned 90 degrees about z. Parent: moving along x from 0 to 10 over 1 s.
  // Child: 1 along x of its parent, holding the mesh (twice: the parent is shared).
  double s = std::sqrt(0.5);
  int child = gltf.Node({{"translation", {1, 0, 0}}, {"mesh", mesh}, {"name", "child"}}, false);
  int sibling = gltf.Node({{"translation", {0, 2, 0}}, {"mesh", mesh}}, false);
  int parent = gltf.Node({{"children", {child, sibling}}}, false);
  gltf.Node({{"rotation", {0, 0, s, s}}, {"children", {parent}}}, true);
  int times = gltf.Floats({0, 1}, "SCALAR");
  int values = gltf.Floats({0, 0, 0, 10, 0, 0}, "VEC3");
  gltf.Animate(parent, "translation", times, values);
  Scene scene = gltf.Import();
  ASSERT_EQ(scene.shapes.size(), 2u);
  EXPECT_EQ(scene.render.frameCount, 25);  // frames 0..24 at 24 per second
  const Shape& shape = scene.shapes[0];
  EXPECT_EQ(shape.name, "child");
  // Frame 12 is 0.5 s: the parent is at x = 5, the child at (6, 0, 0) before the turn.
  ExpectNear(shape.motion.WorldFromObject(12).Apply({0, 0, 0}), {0, 6, 0});
  ExpectNear(shape.motion.WorldFromObject(12).Apply({1, 0, 0}), {0, 7, 0});
  ExpectNear(scene.shapes[1].motion.WorldFromObject(24).Apply({0, 0, 0}), {-2, 10, 0});
  ASSERT_TRUE(shape.motion.parent);
  EXPECT_EQ(shape.motion.parent, scene.shapes[1].motion.parent);  // built once, shared
  EXPECT_TRUE(shape.Moves());
  ExpectRoundTrip(scene);

  ImportOptions options;
  options.framesPerSecond = 30;
  EXPECT_EQ(gltf.Import(options).render.frameCount, 31);
}

// A mesh several nodes place enters the scene's table once, in its own space; one placed
// by a single node stays inline.
TEST(GltfImporterTest, MeshOfSeveralNodesIsSharedOnce) {
  GltfBuilder gltf;
  int tree = gltf.Mesh(kTriangle);
  int rock = gltf.Mesh(kTriangle);
  int twin = gltf.Mesh({0, 0, 0, 2, 0, 0, 0, 2, 0});
  gltf.doc()["meshes"][tree]["name"] = "tree";
  gltf.doc()["meshes"][twin]["name"] = "tree";  // a repeated name takes its index
  for (int i = 0; i < 3; ++i) gltf.Node({{"mesh", tree}, {"translation", {i, 0, 0}}}, true);
  gltf.Node({{"mesh", rock}}, true);
  gltf.Node({{"mesh", twin}}, true);
  gltf.Node({{"mesh", twin}, {"scale", {1, 2, 1}}}, true);
  Scene scene = gltf.Import();
  ASSERT_EQ(scene.shapes.size(), 6u);
  ASSERT_EQ(scene.meshes.size(), 2u);
  ASSERT_TRUE(scene.meshes.count("tree") && scene.meshes.count("tree#2"));
  for (int i = 0; i < 3; ++i) {
    const Shape& shape = scene.shapes[static_cast<size_t>(i)];
    EXPECT_EQ(shape.meshRef, "tree");
    EXPECT_EQ(shape.sharedMesh, scene.meshes.at("tree"));
    EXPECT_TRUE(shape.mesh.vertices.empty());
    ExpectNear(shape.motion.WorldFromObject(0).Apply({0, 0, 0}), {static_cast<double>(i), 0, 0});
  }
  EXPECT_FALSE(scene.shapes[3].SharesMesh());
  EXPECT_EQ(scene.shapes[3].mesh.vertices.size(), 3u);
  EXPECT_EQ(scene.shapes[5].meshRef, "tree#2");
  ExpectNear(scene.meshes.at("tree#2")->vertices[1], {2, 0, 0});  // the mesh's own space
  ExpectRoundTrip(scene);
}

TEST(GltfImporterTest, KeyframedRotationStepAndCubicSpline) {
  GltfBuilder gltf;
  int mesh = gltf.Mesh(kTriangle);
  int node = gltf.Node({{"mesh", mesh}}, true);
  int other = gltf.Node({{"mesh", mesh}}, true);
  double s = std::sqrt(0.5);
  int times = gltf.Floats({0, 0.5, 1}, "SCALAR");
  // Identity, 90 degrees about y, 180 degrees about y (x, y, z, w).
  int rotations = gltf.Floats({0, 0, 0, 1, 0, s, 0, s, 0, 1, 0, 0}, "VEC4");
  // Cubic spline translation: (in-tangent, value, out-tangent) per key, tangents per second.
  int splineTimes = gltf.Floats({0, 1}, "SCALAR");
  int spline = gltf.Floats({0, 0, 0, 0, 0, 0, 48, 0, 0, 0, 0, 0, 2, 0, 0, 0, 0, 0}, "VEC3");
  gltf.Animate(node, "rotation", times, rotations, "STEP");
  gltf.Animate(other, "translation", splineTimes, spline, "CUBICSPLINE");
  Scene scene = gltf.Import();
  ASSERT_EQ(scene.shapes.size(), 2u);
  const Motion& turning = scene.shapes[0].motion;
  // At the key time 0.5 s (frame 12): 90 degrees about y takes +x to -z.
  ExpectNear(turning.WorldFromObject(12).Apply({1, 0, 0}), {0, 0, -1});
  // STEP holds the key until the next one.
  ExpectNear(turning.WorldFromObject(23.9).Apply({1, 0, 0}), {0, 0, -1});
  ExpectNear(turning.WorldFromObject(24).Apply({1, 0, 0}), {-1, 0, 0});
  const Motion& sliding = scene.shapes[1].motion;
  ASSERT_EQ(sliding.translation.keys().size(), 2u);
  EXPECT_EQ(sliding.translation.interpolation(), Interpolation::kCubicSpline);
  EXPECT_DOUBLE_EQ(sliding.translation.keys()[0].outTangent.x, 2.0);  // 48 per second / 24
  ExpectNear(sliding.WorldFromObject(24).Apply({0, 0, 0}), {2, 0, 0});
  // Half way: h01(0.5) * 2 + h10(0.5) * 2 per frame * 24 frames = 1 + 0.125 * 48 = 7.
  ExpectNear(sliding.WorldFromObject(12).Apply({0, 0, 0}), {7, 0, 0});
  ExpectRoundTrip(scene);
}

TEST(GltfImporterTest, MatrixIsDecomposedAndShearRefused) {
  GltfBuilder gltf;
  int mesh = gltf.Mesh(kTriangle);
  // Column-major: scale 2, turned 90 degrees about z, moved to (1, 2, 3).
  gltf.Node({{"mesh", mesh}, {"matrix", {0, 2, 0, 0, -2, 0, 0, 0, 0, 0, 2, 0, 1, 2, 3, 1}}}, true);
  Scene scene = gltf.Import();
  ExpectNear(scene.shapes[0].motion.WorldFromObject(0).Apply({1, 0, 0}), {1, 4, 3});
  ExpectNear(scene.shapes[0].motion.WorldFromObject(0).Apply({0, 0, 1}), {1, 2, 5});
  gltf.doc()["nodes"][0]["matrix"] = {1, 0, 0, 0, 0.5, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  std::string what = ErrorOf([&] { gltf.Import(); });
  EXPECT_NE(what.find("scene/nodes/0/matrix: the gltf scene: a matrix with shear"), std::string::npos) << what;
  gltf.doc()["nodes"][0]["matrix"] = {1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  what = ErrorOf([&] { gltf.Import(); });
  EXPECT_NE(what.find("scene/nodes/0/matrix: the gltf scene: a singular matrix"), std::string::npos) << what;
}

TEST(GltfImporterTest, CameraLightsAndMaterials) {
  GltfBuilder gltf;
  int mesh = gltf.Mesh(kTriangle);
  gltf.doc()["meshes"][0]["primitives"][0]["material"] = 0;
  gltf.doc()["materials"] = json::parse(R"([
      {"name": "gold", "pbrMetallicRoughness": {"baseColorFactor": [1, 0.5, 0, 1], "metallicFactor": 1,
                                                "roughnessFactor": 0.5}},
      {"name": "glass", "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1], "metallicFactor": 0,
                                                 "roughnessFactor": 0},
       "extensions": {"KHR_materials_transmission": {"transmissionFactor": 0.9}, "KHR_materials_ior": {"ior": 1.33}}}])");
  gltf.doc()["cameras"] =
      json::parse(R"([{"type": "perspective", "perspective": {"yfov": 1.0471975511965976, "znear": 0.1}}])");
  gltf.doc()["extensionsUsed"] = {"KHR_lights_punctual"};
  gltf.doc()["extensions"] = json::parse(R"({"KHR_lights_punctual": {"lights": [
      {"type": "point", "color": [1, 0.5, 0.25], "intensity": 8}, {"type": "directional", "intensity": 2}]}})");
  gltf.Node({{"mesh", mesh}}, true);
  gltf.Node({{"camera", 0}, {"translation", {0, 1, 5}}, {"name", "eye"}}, true);
  gltf.Node(json::parse(R"({"translation": [3, 4, 5], "extensions": {"KHR_lights_punctual": {"light": 0}}})"), true);
  // Turned 90 degrees about x: its -z becomes -y, straight down.
  double s = std::sqrt(0.5);
  json sun = json::parse(R"({"extensions": {"KHR_lights_punctual": {"light": 1}}})");
  sun["rotation"] = {-s, 0, 0, s};
  gltf.Node(sun, true);
  Scene scene = gltf.Import();

  CameraPose pose = scene.camera.At(0);
  ExpectNear(pose.position, {0, 1, 5});
  ExpectNear(pose.lookAt, {0, 1, 4});
  EXPECT_NEAR(scene.camera.verticalFovDegrees, 60, 1e-9);  // yfov pi / 3
  EXPECT_EQ(scene.render.width, 640);
  EXPECT_EQ(scene.render.height, 480);

  ASSERT_EQ(scene.lights.size(), 2u);
  EXPECT_EQ(scene.lights[0].type, Light::Type::kPoint);
  ExpectNear(scene.lights[0].PositionAt(0), {3, 4, 5});
  // Candela and lux become W/sr and W/m2 at 683 lm/W, as the tools that write glTF convert.
  ExpectNear(scene.lights[0].intensity.Evaluate(0), {8.0 / 683, 4.0 / 683, 2.0 / 683});
  EXPECT_EQ(scene.lights[1].type, Light::Type::kDirectional);
  ExpectNear(scene.lights[1].DirectionAt(0), {0, -1, 0});
  ExpectNear(scene.lights[1].intensity.Evaluate(0), {2.0 / 683, 2.0 / 683, 2.0 / 683});
  ImportOptions asTheyAre;
  asTheyAre.lightUnits = LightUnits::kRadiometric;
  ExpectNear(gltf.Import(asTheyAre).lights[0].intensity.Evaluate(0), {8, 4, 2});

  ASSERT_EQ(scene.materials.size(), 3u);  // default, glass, gold: the parser's order
  EXPECT_EQ(scene.materials[0].name, "default");
  ASSERT_TRUE(scene.materials[0].IsPbr());  // glTF's default: white, metallic, rough
  EXPECT_DOUBLE_EQ(scene.materials[0].pbr->metallic, 1);
  const Material& glass = scene.materials[1];
  const Material& gold = scene.materials[2];
  EXPECT_EQ(gold.name, "gold");
  EXPECT_EQ(scene.shapes[0].material, 2);
  ASSERT_TRUE(gold.IsPbr() && glass.IsPbr());
  ExpectNear(gold.pbr->baseColor, {1, 0.5, 0});
  EXPECT_DOUBLE_EQ(gold.pbr->metallic, 1);
  EXPECT_DOUBLE_EQ(gold.pbr->roughness, 0.5);
  EXPECT_FALSE(gold.Reflects());  // rougher than a mirror: lights only
  EXPECT_DOUBLE_EQ(glass.pbr->transmission, 0.9);
  EXPECT_DOUBLE_EQ(glass.pbr->ior, 1.33);
  EXPECT_TRUE(glass.Reflects());
  EXPECT_TRUE(glass.Refracts());
  ExpectRoundTrip(scene);

  ImportOptions options;
  options.camera = "nobody";
  EXPECT_NE(ErrorOf([&] { gltf.Import(options); }).find("no camera node named or numbered \"nobody\""),
            std::string::npos);
  options.camera = "eye";
  options.width = 320;
  options.height = 200;
  options.samplesPerPixel = 4;
  Scene sized = gltf.Import(options);
  EXPECT_EQ(sized.render.width, 320);
  EXPECT_EQ(sized.render.samplesPerPixel, 4);

  // Orthographic: ymag is half the view's height.
  gltf.doc()["cameras"][0] =
      json::parse(R"({"type": "orthographic", "orthographic": {"xmag": 1.5, "ymag": 1.25, "znear": 0.1, "zfar": 10}})");
  Scene orthographic = gltf.Import();
  EXPECT_TRUE(orthographic.camera.orthographic);
  EXPECT_DOUBLE_EQ(orthographic.camera.orthographicHeight, 2.5);
  ExpectRoundTrip(orthographic);
  gltf.doc()["cameras"][0]["orthographic"]["ymag"] = 0;
  std::string what = ErrorOf([&] { gltf.Import(); });
  EXPECT_NE(what.find("scene/cameras/0/orthographic/ymag"), std::string::npos) << what;
}

TEST(GltfImporterTest, RefusesWhatItCannotHold) {
  GltfBuilder gltf;
  int mesh = gltf.Mesh(kTriangle);
  gltf.Node({{"mesh", mesh}}, true);
  gltf.doc()["extensionsRequired"] = {"KHR_texture_basisu"};
  std::string what = ErrorOf([&] { gltf.Import(); });
  EXPECT_NE(what.find("scene/extensionsRequired/0: the gltf scene: the file requires extension "
                      "\"KHR_texture_basisu\""),
            std::string::npos)
      << what;
  gltf.doc().erase("extensionsRequired");
  gltf.doc()["extensionsUsed"] = {"EXT_unknown_optional"};
  EXPECT_EQ(gltf.Import().shapes.size(), 1u);

  int times = gltf.Floats({0, 1, 1}, "SCALAR");
  int values = gltf.Floats({0, 0, 0, 1, 0, 0, 2, 0, 0}, "VEC3");
  gltf.Animate(0, "translation", times, values);
  what = ErrorOf([&] { gltf.Import(); });
  EXPECT_NE(what.find("scene/accessors/" + std::to_string(times) +
                      ": the gltf scene: key time 2 (1.000000 s) does not follow key 1; expected strictly increasing"),
            std::string::npos)
      << what;

  GltfBuilder external;
  external.Node({{"mesh", external.Mesh(kTriangle)}}, true);
  std::string text = external.Text();
  json doc = json::parse(text);
  doc["buffers"][0]["uri"] = "mesh.bin";
  what = ErrorOf([&] { ImportSceneBytes(doc.dump(), "gltf"); });
  EXPECT_NE(what.find("scene/buffers/0/uri: the gltf scene: buffer file \"mesh.bin\" cannot be read: the file was "
                      "submitted without a folder"),
            std::string::npos)
      << what;
}

TEST(GltfImporterTest, InterleavedStrideAndNormalizedUvs) {
  GltfBuilder gltf;
  // Position and normal interleaved, 24 bytes per vertex, in one view; UVs as normalized bytes.
  std::vector<double> interleaved = {0, 0, 0, 0, 0, 1, 2, 0, 0, 0, 0, 1, 0, 2, 0, 0, 0, 1};
  int both = gltf.Floats(interleaved, "VEC3");
  json& accessors = gltf.doc()["accessors"];
  json& views = gltf.doc()["bufferViews"];
  views[accessors[both]["bufferView"].get<size_t>()]["byteStride"] = 24;
  accessors[both]["count"] = 3;
  json normals = accessors[both];
  normals["byteOffset"] = 12;
  accessors.push_back(normals);
  const size_t normalsIndex = accessors.size() - 1;
  int uvs = gltf.Indices({0, 0, 0, 0});  // replaced below by normalized unsigned bytes
  accessors[uvs] = {{"bufferView", accessors[uvs]["bufferView"]},
                    {"componentType", 5121},
                    {"normalized", true},
                    {"type", "VEC2"},
                    {"count", 3}};
  gltf.doc()["meshes"].push_back(json::parse(R"({"primitives": [{"attributes": {}}]})"));
  json& attributes = gltf.doc()["meshes"][0]["primitives"][0]["attributes"];
  attributes["POSITION"] = both;
  attributes["NORMAL"] = normalsIndex;
  attributes["TEXCOORD_0"] = uvs;
  gltf.Node({{"mesh", 0}}, true);
  Scene scene = gltf.Import();
  ASSERT_EQ(scene.shapes.size(), 1u);
  const TriangleMesh& mesh = scene.shapes[0].mesh;
  ASSERT_EQ(mesh.vertices.size(), 3u);
  ExpectNear(mesh.vertices[1], {2, 0, 0}, 0);
  ExpectNear(mesh.vertices[2], {0, 2, 0}, 0);
  ASSERT_EQ(mesh.normals.size(), 3u);
  ExpectNear(mesh.normals[2], {0, 0, 1}, 0);
  ASSERT_EQ(mesh.uvs.size(), 3u);
  EXPECT_EQ(mesh.uvs[0][0], 0);
  ExpectRoundTrip(scene);

  accessors[both]["count"] = 4;  // one element past the view
  std::string what = ErrorOf([&] { gltf.Import(); });
  EXPECT_NE(what.find("scene/accessors/" + std::to_string(both) +
                      ": the gltf scene: 4 elements from byte 0 run past "
                      "the end of buffer view"),
            std::string::npos)
      << what;
  accessors[both]["count"] = 3;
  accessors[both]["sparse"] = json::parse(R"({"count": 1, "indices": {"bufferView": 0, "componentType": 5126},
                                              "values": {"bufferView": 0}})");
  what = ErrorOf([&] { gltf.Import(); });
  EXPECT_NE(what.find("scene/accessors/" + std::to_string(both) +
                      "/sparse/indices/componentType: the gltf scene: FLOAT; expected UNSIGNED_BYTE, UNSIGNED_SHORT or "
                      "UNSIGNED_INT indices"),
            std::string::npos)
      << what;
}

TEST(GltfImporterTest, VertexColoursFromFloatsOrNormalizedIntegers) {
  GltfBuilder gltf;
  const int mesh = gltf.Mesh({0, 0, 0, 1, 0, 0, 0, 1, 0});
  json& attributes = gltf.doc()["meshes"][mesh]["primitives"][0]["attributes"];
  // RGBA as normalized unsigned bytes: the alpha is dropped.
  attributes["COLOR_0"] = gltf.Integers({255, 0, 0, 255, 0, 51, 0, 128, 0, 0, 255, 0}, 5121, "VEC4", true);
  gltf.Node({{"mesh", mesh}}, true);
  Scene scene = gltf.Import();
  const TriangleMesh& imported = scene.shapes.at(0).mesh;
  ASSERT_EQ(imported.colors.size(), 3u);
  ExpectNear(imported.colors[0], {1, 0, 0}, 0);
  ExpectNear(imported.colors[1], {0, 0.2, 0}, 1e-12);
  ExpectNear(imported.colors[2], {0, 0, 1}, 0);
  ExpectRoundTrip(scene);

  attributes["COLOR_0"] = gltf.Floats({1, 1, 1, 0.5, 0.5, 0.5, 0, 0, 0}, "VEC3");
  ExpectNear(gltf.Import().shapes.at(0).mesh.colors[1], {0.5, 0.5, 0.5}, 0);

  const int raw = gltf.Integers({255, 0, 0, 0, 255, 0, 0, 0, 255}, 5121, "VEC3");
  attributes["COLOR_0"] = raw;
  std::string what = ErrorOf([&] { gltf.Import(); });
  EXPECT_NE(what.find("scene/accessors/" + std::to_string(raw) +
                      "/normalized: the gltf scene: integer colours that are not normalized"),
            std::string::npos)
      << what;
  const int two = gltf.Floats({1, 0, 0, 0, 1, 0}, "VEC3");
  attributes["COLOR_0"] = two;
  what = ErrorOf([&] { gltf.Import(); });
  EXPECT_NE(what.find("scene/accessors/" + std::to_string(two) + "/count: the gltf scene: 2 colours for 3 positions"),
            std::string::npos)
      << what;
  const int negative = gltf.Floats({1, 0, 0, 0, -0.5, 0, 0, 0, 1}, "VEC3");
  attributes["COLOR_0"] = negative;
  what = ErrorOf([&] { gltf.Import(); });
  EXPECT_NE(what.find("scene/accessors/" + std::to_string(negative) + ": the gltf scene: colour 1 has a negative"),
            std::string::npos)
      << what;
}

TEST(GltfImporterTest, SpotLightsKeepTheirConeAndShineDownTheirNode) {
  GltfBuilder gltf;
  gltf.Node({{"mesh", gltf.Mesh(kTriangle)}}, true);
  gltf.doc()["extensions"] = json::parse(R"({"KHR_lights_punctual": {"lights": [
      {"type": "spot", "intensity": 5, "spot": {"innerConeAngle": 0.25, "outerConeAngle": 0.5}}]}})");
  // Turned a quarter about x: its -z axis points down.
  gltf.Node(json::parse(R"({"translation": [0, 3, 0], "rotation": [-0.7071067811865476, 0, 0, 0.7071067811865476],
                            "extensions": {"KHR_lights_punctual": {"light": 0}}})"), true);
  Scene scene = gltf.Import();
  ASSERT_EQ(scene.lights.size(), 1u);
  EXPECT_EQ(scene.lights[0].type, Light::Type::kSpot);
  ExpectNear(scene.lights[0].PositionAt(0), {0, 3, 0});
  ExpectNear(scene.lights[0].DirectionAt(0), {0, -1, 0});
  EXPECT_NEAR(scene.lights[0].outerConeDegrees, 0.5 * 180 / M_PI, 1e-9);
  EXPECT_NEAR(scene.lights[0].innerConeDegrees, 0.25 * 180 / M_PI, 1e-9);
  ExpectNear(scene.lights[0].intensity.Evaluate(0), {5.0 / 683, 5.0 / 683, 5.0 / 683});  // candela to W/sr
  ExpectRoundTrip(scene);
}

class TempFolder {
 public:
  TempFolder() {
    static std::atomic<int> counter{0};
    path_ = fs::temp_directory_path() /
            ("tcfarm_gltf_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::create_directories(path_ / "scene");
  }
  ~TempFolder() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

TEST(GltfImporterTest, ExternalFilesStayInsideTheFolder) {
  TempFolder folder;
  GltfBuilder gltf;
  gltf.Node({{"mesh", gltf.Mesh(kTriangle)}}, true);
  json doc = json::parse(gltf.Text());
  // The buffer as a file beside the scene (its name URI-encoded).
  doc["buffers"][0]["uri"] = "mesh%20data.bin";
  auto write = [&](const fs::path& path, const std::string& content) {
    std::ofstream(path, std::ios::binary) << content;
    return path;
  };
  // The bytes the builder wrote: the triangle's floats, its only accessor.
  std::string raw;
  for (double v : kTriangle) {
    float f = static_cast<float>(v);
    raw.append(reinterpret_cast<const char*>(&f), 4);
  }
  write(folder.path() / "scene" / "mesh data.bin", raw);
  fs::path scenePath = write(folder.path() / "scene" / "model.gltf", doc.dump());
  EXPECT_EQ(ImportScene(scenePath).shapes.size(), 1u);

  // A missing image is refused, though images are not decoded.
  doc["images"] = json::parse(R"([{"uri": "wood.png"}])");
  write(scenePath, doc.dump());
  std::string what = ErrorOf([&] { ImportScene(scenePath); });
  EXPECT_NE(what.find("scene/images/0/uri: model.gltf: image file \"wood.png\" is missing"), std::string::npos) << what;
  write(folder.path() / "scene" / "wood.png", "not even a PNG: never decoded");
  EXPECT_EQ(ImportScene(scenePath).shapes.size(), 1u);

  // A buffer outside the scene's folder is refused, even when it exists.
  write(folder.path() / "secret.bin", raw);
  doc["buffers"][0]["uri"] = "../secret.bin";
  write(scenePath, doc.dump());
  what = ErrorOf([&] { ImportScene(scenePath); });
  EXPECT_NE(what.find("scene/buffers/0/uri: model.gltf: buffer file \"../secret.bin\" resolves outside the scene "
                      "folder"),
            std::string::npos)
      << what;
}

TEST(GltfImporterTest, SniffsGltfBeforeTcfarmJson) {
  EXPECT_EQ(FindImporterForFile("upload", "{\"asset\": {\"version\": \"2.0\"}}")->Type(), "gltf");
  EXPECT_EQ(FindImporterForFile("upload", std::string("glTF\x02\0\0\0", 8))->Type(), "gltf");
  EXPECT_EQ(FindImporterForFile("upload", "{\"camera\": {}}")->Type(), "tcfarm-json");
  EXPECT_EQ(FindImporterForFile("upload", "{\"materials\": {\"asset\": {}}, \"x\": \"\\\"asset\\\": 1\"}")->Type(),
            "tcfarm-json");
  EXPECT_EQ(FindImporterForFile("upload", "{\"extras\": [\"}\"], \"asset\" : {}")->Type(), "gltf");
  EXPECT_EQ(FindImporterForFile("a/Box.GLB", "")->Type(), "gltf");
}

// --- Debian's assimp-testmodels: good files import, broken ones are refused where they break.

std::string ModelError(const std::string& relative) {
  return ErrorOf([&] { ImportScene(kTestModels / relative); });
}

TEST(GltfImporterTest, BrokenTestModelsAreRefusedWithTheirPointers) {
  TCFARM_REQUIRE_TOOL(fs::exists(kTestModels), "assimp-testmodels is not installed (scripts/bootstrap)");
  struct Case {
    const char* file;
    const char* message;
  };
  const Case cases[] = {
      {"IndexOutOfRange/IndexOutOfRange.gltf",
       "scene/accessors/0: IndexOutOfRange.gltf: index 0 is 255, out of range for 24 vertices"},
      {"IndexOutOfRange/AllIndicesOutOfRange.gltf", "scene/accessors/0: AllIndicesOutOfRange.gltf: index 0 is 65535"},
      {"BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb",
       "scene/accessors/2: BoxWithInfinites.glb: position 0 holds an infinity"},
      {"RecursiveNodes/RecursiveNodes.gltf",
       "scene/nodes/0: RecursiveNodes.gltf: node 0 is its own ancestor (a recursive node graph)"},
      {"MissingBin/BoxTextured.gltf",
       "scene/buffers/0/uri: BoxTextured.gltf: buffer file \"BoxTextured0.bin\" is missing"},
      {"SchemaFailures/sceneWrongType.gltf",
       "scene/scene: sceneWrongType.gltf: a value of JSON type string; expected a non-negative integer"},
      {"wrongTypes/badArray.gltf",
       "scene/meshes/0/primitives: badArray.gltf: a value of JSON type object; expected an array"},
      {"wrongTypes/badObject.gltf",
       "scene/materials/0/pbrMetallicRoughness: badObject.gltf: a value of JSON type array"},
      {"wrongTypes/badString.gltf",
       "scene/scenes/0/name: badString.gltf: a value of JSON type number; expected a string"},
      {"wrongTypes/badNumber.gltf", "scene/materials/0/normalTexture/scale: badNumber.gltf"},
      {"wrongTypes/badUint.gltf", "scene/materials/0/pbrMetallicRoughness/baseColorTexture/index: badUint.gltf"},
      {"wrongTypes/badExtension.gltf",
       "scene/materials/0/pbrMetallicRoughness/baseColorTexture/extensions/KHR_texture_transform: badExtension.gltf"},
  };
  for (const Case& c : cases) {
    std::string what = ModelError(c.file);
    EXPECT_NE(what.find(c.message), std::string::npos) << c.file << ": " << what;
  }
}

TEST(GltfImporterTest, TruncatedGlbNamesTheByteOffset) {
  const fs::path path = kTestModels / "BoxTextured-glTF-Binary/BoxTextured.glb";
  TCFARM_REQUIRE_TOOL(fs::exists(path), "assimp-testmodels is not installed (scripts/bootstrap)");
  std::ifstream in(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(ImportSceneBytes(bytes, "").shapes.size(), 1u);
  std::string what = ErrorOf([&] { ImportSceneBytes(bytes.substr(0, bytes.size() / 2), ""); });
  EXPECT_NE(
      what.find("scene: the gltf scene: GLB byte 8: the header gives a length of " + std::to_string(bytes.size()) +
                " bytes but the file holds " + std::to_string(bytes.size() / 2) + " (truncated)"),
      std::string::npos)
      << what;
  what = ErrorOf([&] { ImportSceneBytes(bytes.substr(0, 10), "gltf"); });
  EXPECT_NE(what.find("GLB byte 10: the file ends inside its header"), std::string::npos) << what;
}

// A GLB file: the 12-byte header, the JSON chunk and, when there is one, the BIN chunk,
// each chunk padded to 4 bytes as the format requires.
std::string Glb(const json& document, const std::string& binary) {
  auto u32 = [](uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); };
  std::string text = document.dump();
  text.resize((text.size() + 3) / 4 * 4, ' ');
  std::string chunks = u32(static_cast<uint32_t>(text.size())) + "JSON" + text;
  if (!binary.empty()) {
    std::string padded = binary;
    padded.resize((padded.size() + 3) / 4 * 4, '\0');
    chunks += u32(static_cast<uint32_t>(padded.size())) + std::string("BIN\0", 4) + padded;
  }
  return "glTF" + u32(2) + u32(static_cast<uint32_t>(12 + chunks.size())) + chunks;
}

// Found by tests/fuzz/gltf_fuzz: tinygltf passes an image's bufferView to the image loader
// unchecked, and a view one byte past its buffer was read out of bounds.
TEST(GltfImporterTest, ImageViewPastItsBufferIsRefused) {
  json document = {{"asset", {{"version", "2.0"}}},
                   {"images", json::array({json{{"bufferView", 0}, {"mimeType", "image/png"}}})},
                   {"bufferViews", json::array({json{{"buffer", 0}, {"byteOffset", 4}, {"byteLength", 9}}})},
                   {"buffers", json::array({json{{"byteLength", 12}}})}};
  std::string what = ErrorOf([&] { ImportSceneBytes(Glb(document, std::string(12, 'x')), "gltf"); });
  EXPECT_NE(what.find("image 0's bufferView 0 (bytes 4 + 9) runs past the end of buffer 0 (12 bytes)"),
            std::string::npos)
      << what;
  document["bufferViews"][0]["byteOffset"] = 4000000000u;
  what = ErrorOf([&] { ImportSceneBytes(Glb(document, std::string(12, 'x')), "gltf"); });
  EXPECT_NE(what.find("runs past the end of buffer 0 (12 bytes)"), std::string::npos) << what;
  // The same view inside its buffer is read.
  document["bufferViews"][0]["byteOffset"] = 3;
  what = ErrorOf([&] { ImportSceneBytes(Glb(document, std::string(12, 'x')), "gltf"); });
  EXPECT_EQ(what.find("runs past"), std::string::npos) << what;
}

TEST(GltfImporterTest, GoodTestModelsImportAndReadBack) {
  TCFARM_REQUIRE_TOOL(fs::exists(kTestModels), "assimp-testmodels is not installed (scripts/bootstrap)");
  for (const char* file :
       {"BoxTextured-glTF/BoxTextured.gltf", "BoxTextured-glTF-Binary/BoxTextured.glb",
        "BoxTextured-glTF-Embedded/BoxTextured.gltf", "2CylinderEngine-glTF-Binary/2CylinderEngine.glb",
        "cameras/Cameras.gltf", "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_04.gltf",
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_05.gltf",
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_06.gltf"}) {
    Scene scene = ImportScene(kTestModels / file);
    EXPECT_FALSE(scene.shapes.empty()) << file;
    ExpectRoundTrip(scene);
  }
}

// --- skins and morph targets ------------------------------------------------------------

// Every shape's vertices at `frame`, deformed where the shape deforms, in world space.
std::vector<Vec3> WorldVertices(const Shape& shape, double frame) {
  std::vector<Vec3> vertices =
      shape.deformation ? Deform(shape.Mesh(), *shape.deformation, frame).positions : shape.Mesh().vertices;
  const Affine worldFromObject = shape.motion.WorldFromObject(frame);
  for (Vec3& v : vertices) v = worldFromObject.Apply(v);
  return vertices;
}

// The round trip keeps every bit, and the scene read back deforms to the same bits.
void ExpectDeformedRoundTrip(const Scene& scene, const std::vector<double>& frames) {
  ExpectRoundTrip(scene);
  Scene back = ParseScene(SerializeScene(scene));
  ASSERT_EQ(back.shapes.size(), scene.shapes.size());
  for (size_t s = 0; s < scene.shapes.size(); ++s) {
    ASSERT_EQ(!back.shapes[s].deformation, !scene.shapes[s].deformation);
    for (double frame : frames) {
      const std::vector<Vec3> a = WorldVertices(scene.shapes[s], frame), b = WorldVertices(back.shapes[s], frame);
      ASSERT_EQ(a.size(), b.size());
      for (size_t v = 0; v < a.size(); ++v) {
        EXPECT_EQ(std::memcmp(&a[v], &b[v], sizeof(Vec3)), 0) << "shape " << s << " vertex " << v << " frame " << frame;
      }
    }
  }
}

// A way to spoil a fresh fixture (a SkinnedStrip, a MorphingSquare) and what importing it
// must then say.
template <typename Fixture>
struct Refusal {
  std::function<void(Fixture&)> spoil;
  std::function<std::string(const Fixture&)> message;
};

template <typename Fixture>
void ExpectRefusals(const std::vector<Refusal<Fixture>>& refusals) {
  for (const Refusal<Fixture>& refusal : refusals) {
    Fixture fixture;
    refusal.spoil(fixture);
    std::string what = ErrorOf([&] { fixture.gltf.Import(); });
    EXPECT_NE(what.find(refusal.message(fixture)), std::string::npos) << what;
  }
}

TEST(GltfImporterTest, SkinBendsTheStripAtTheKnee) {
  SkinnedStrip strip;
  Scene scene = strip.gltf.Import();
  ASSERT_EQ(scene.shapes.size(), 1u);
  const Shape& shape = scene.shapes[0];
  ASSERT_TRUE(shape.deformation && shape.deformation->hasSkin && !shape.deformation->hasMorph);
  EXPECT_TRUE(shape.Deforms());
  EXPECT_TRUE(shape.motion.IsNone());  // the node's own move along x is ignored
  const Skin& skin = shape.deformation->skin;
  EXPECT_EQ(skin.influencesPerVertex, 4);
  EXPECT_EQ(skin.joints.size(), 2u);
  // Frame 0: the bind pose, every skin matrix the identity.
  const std::vector<Vec3> rest = WorldVertices(shape, 0);
  ExpectNear(rest[2], {0, 1, 0});
  ExpectNear(rest[5], {1, 2, 0});
  // Frame 24 (1 s): the knee at (0.5, 1, 0) has turned a quarter about z.
  // Top row: about the knee, (1, 2) - (0.5, 1) = (0.5, 1) turns to (-1, 0.5).
  const std::vector<Vec3> bent = WorldVertices(shape, 24);
  ExpectNear(bent[5], {-0.5, 1.5, 0});
  ExpectNear(bent[4], {-0.5, 0.5, 0});
  ExpectNear(bent[0], {0, 0, 0});  // the hip's row stays
  // The middle row half and half: (0, 1) and, about the knee, (0.5, 0.5).
  ExpectNear(bent[2], {0.25, 0.75, 0});
  EXPECT_FALSE(skin.SameAt(0, 24));
  EXPECT_TRUE(skin.SameAt(24, 30));  // held after the last key
  ExpectDeformedRoundTrip(scene, {0, 7.5, 24});
}

TEST(GltfImporterTest, EightInfluencesAndOnlyTheJointsAPrimitiveUses) {
  SkinnedStrip strip;
  // A third joint that no vertex of the strip leans on, and a second set of influences
  // (JOINTS_1, WEIGHTS_1) holding the knee's share of the middle row.
  int toe = strip.gltf.Node({{"translation", {0, 1, 0}}}, false);
  strip.gltf.doc()["nodes"][strip.knee]["children"] = {toe};
  strip.gltf.doc()["skins"][0]["joints"].push_back(toe);
  strip.gltf.doc()["skins"][0].erase("inverseBindMatrices");  // identities
  json& attributes = strip.gltf.doc()["meshes"][0]["primitives"][0]["attributes"];
  attributes["WEIGHTS_0"] = strip.gltf.Floats(
      {1, 0, 0, 0, 1, 0, 0, 0, 0.5, 0, 0, 0, 0.5, 0, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0}, "VEC4");
  attributes["JOINTS_1"] = strip.gltf.Integers(std::vector<int>(24, 1), 5121, "VEC4");
  attributes["WEIGHTS_1"] = strip.gltf.Floats(
      {0, 0, 0, 0, 0, 0, 0, 0, 0.5, 0, 0, 0, 0.5, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0}, "VEC4");
  Scene scene = strip.gltf.Import();
  const Skin& skin = scene.shapes[0].deformation->skin;
  EXPECT_EQ(skin.influencesPerVertex, 8);
  EXPECT_EQ(skin.joints.size(), 2u);  // the toe moves none of its vertices
  EXPECT_EQ(skin.vertexJoints[2 * 8 + 4], 1u);
  EXPECT_EQ(skin.vertexWeights[2 * 8 + 4], 0.5);
  // Identity inverse binds: the skin matrices are the joints' world transforms.
  ExpectNear(WorldVertices(scene.shapes[0], 0)[0], {0.5, 0, 0});
  ExpectDeformedRoundTrip(scene, {0, 12, 24});

  attributes.erase("WEIGHTS_1");
  std::string what = ErrorOf([&] { strip.gltf.Import(); });
  EXPECT_NE(what.find("scene/meshes/0/primitives/0/attributes: the gltf scene: JOINTS_1 alone"), std::string::npos)
      << what;
  attributes.erase("JOINTS_1");
  attributes.erase("JOINTS_0");
  what = ErrorOf([&] { strip.gltf.Import(); });
  EXPECT_NE(what.find("scene/meshes/0/primitives/0/attributes: the gltf scene: WEIGHTS_0 alone, though node 0 binds "
                      "the mesh to skin 0"),
            std::string::npos)
      << what;
}

TEST(GltfImporterTest, BadSkinsAreRefusedWithTheirPointers) {
  ExpectRefusals<SkinnedStrip>({
      {[](SkinnedStrip& s) {
         json& attributes = s.gltf.doc()["meshes"][0]["primitives"][0]["attributes"];
         attributes["JOINTS_0"] = s.joints = s.gltf.Integers(
             std::vector<int>{0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 5, 0, 0, 0, 1, 0, 0}, 5121, "VEC4");
       },
       [](const SkinnedStrip& s) {
         return "scene/accessors/" + std::to_string(s.joints) +
                ": the gltf scene: vertex 4 names joint 5 (weight 1.0) of skin 0, which has 2; expected joint "
                "indices below the skin's joint count";
       }},
      {[](SkinnedStrip& s) { s.gltf.doc()["skins"][0]["joints"][1] = s.gltf.Node(json::object(), false); },
       [](const SkinnedStrip&) {
         return "scene/skins/0/joints/1: the gltf scene: joint 1 names node 3, which is not in the rendered scene";
       }},
      {[](SkinnedStrip& s) { s.gltf.doc()["skins"][0]["joints"][1] = 42; },
       [](const SkinnedStrip&) {
         return "scene/skins/0/joints/1: the gltf scene: joint 1 names node 42, which does not exist";
       }},
      {[](SkinnedStrip& s) { s.gltf.doc()["skins"][0]["skeleton"] = s.gltf.Node(json::object(), false); },
       [](const SkinnedStrip&) {
         return "scene/skins/0/skeleton: the gltf scene: the skeleton names node 3, which is not in the rendered "
                "scene";
       }},
      {[](SkinnedStrip& s) { s.gltf.doc()["skins"][0]["skeleton"] = s.knee; },
       [](const SkinnedStrip&) {
         return "scene/skins/0/joints/0: the gltf scene: joint 0 (node 2) is not the skeleton node 1 or below it";
       }},
      {[](SkinnedStrip& s) { s.gltf.doc()["nodes"][s.meshNode]["skin"] = 1; },
       [](const SkinnedStrip&) { return "scene/nodes/0/skin: the gltf scene: skin 1 does not exist"; }},
      {[](SkinnedStrip& s) { s.gltf.doc()["accessors"][s.inverseBind]["count"] = 1; },
       [](const SkinnedStrip& s) {
         return "scene/accessors/" + std::to_string(s.inverseBind) +
                "/count: the gltf scene: 1 inverse bind matrices for 2 joints; expected one per joint";
       }},
      {[](SkinnedStrip& s) {
         s.gltf.doc()["accessors"][s.inverseBind]["type"] = "VEC4";
         s.gltf.doc()["accessors"][s.inverseBind]["count"] = 8;
       },
       [](const SkinnedStrip& s) {
         return "scene/accessors/" + std::to_string(s.inverseBind) +
                ": the gltf scene: VEC4 of FLOAT where /skins/0/inverseBindMatrices refers to it";
       }},
      {[](SkinnedStrip& s) {
         // Matrix 1's first column ends in 0.5: a projective last row.
         s.gltf.doc()["skins"][0]["inverseBindMatrices"] = s.inverseBind = s.gltf.Floats(
             {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1,  //
              1, 0, 0, 0.5, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1},
             "MAT4");
       },
       [](const SkinnedStrip& s) {
         return "scene/accessors/" + std::to_string(s.inverseBind) +
                ": the gltf scene: matrix 1 has the last row 0.5, 0.0, 0.0, 1.0";
       }},
      {[](SkinnedStrip& s) { s.gltf.doc()["accessors"][s.weights]["count"] = 5; },
       [](const SkinnedStrip& s) {
         return "scene/accessors/" + std::to_string(s.weights) +
                "/count: the gltf scene: 5 elements for a primitive of 6 vertices";
       }},
  });
}

// A square of 4 vertices whose morph targets lift its right edge (target 0) and its top
// edge (target 1), as two primitives of one mesh sharing the accessors.
struct MorphingSquare {
  GltfBuilder gltf;
  int right, top, times, node, mesh;

  MorphingSquare() {
    mesh = gltf.Mesh({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}, {0, 1, 2, 0, 2, 3});
    right = gltf.Floats({0, 0, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0}, "VEC3");
    top = gltf.Floats({0, 0, 0, 0, 0, 0, 0, 0, 2, 0, 0, 2}, "VEC3");
    json& primitives = gltf.doc()["meshes"][mesh]["primitives"];
    primitives[0]["targets"] = json::array({json{{"POSITION", right}}, json{{"POSITION", top}}});
    primitives.push_back(primitives[0]);
    node = gltf.Node({{"mesh", mesh}, {"translation", {0, 0, -1}}}, true);
    times = gltf.Floats({0, 0.5, 1}, "SCALAR");
  }
};

TEST(GltfImporterTest, MorphTargetsFollowTheirWeights) {
  MorphingSquare square;
  // LINEAR: target 0 rises to 1 and falls back, target 1 follows half a second behind.
  square.gltf.Animate(square.node, "weights", square.times, square.gltf.Floats({0, 0, 1, 0, 0, 1}, "SCALAR"));
  Scene scene = square.gltf.Import();
  ASSERT_EQ(scene.shapes.size(), 2u);
  EXPECT_EQ(scene.render.frameCount, 25);
  const Shape& shape = scene.shapes[1];
  ASSERT_TRUE(shape.deformation && shape.deformation->hasMorph && !shape.deformation->hasSkin);
  EXPECT_TRUE(shape.Deforms());
  EXPECT_EQ(shape.deformation->morph.TargetCount(), 2u);
  // Placed by its node (morph targets move vertices in the mesh's own space).
  ExpectNear(WorldVertices(shape, 0)[2], {1, 1, -1});
  // Frame 6 (0.25 s): weights (0.5, 0); frame 18 (0.75 s): (0.5, 0.5).
  ExpectNear(WorldVertices(shape, 6)[2], {1, 1, -0.5});
  ExpectNear(WorldVertices(shape, 18)[2], {1, 1, 0.5});
  ExpectNear(WorldVertices(shape, 18)[3], {0, 1, 0});
  ExpectNear(WorldVertices(shape, 18)[0], {0, 0, -1});
  ExpectDeformedRoundTrip(scene, {0, 6, 18, 24});

  // The mesh's default weights, and a node's own that override them; neither animated.
  square.gltf.doc().erase("animations");
  square.gltf.doc()["meshes"][0]["weights"] = {0.25, 0};
  Scene still = square.gltf.Import();
  EXPECT_FALSE(still.shapes[0].Deforms());
  ExpectNear(WorldVertices(still.shapes[0], 0)[1], {1, 0, -0.75});
  square.gltf.doc()["nodes"][0]["weights"] = {0, 1};
  ExpectNear(WorldVertices(square.gltf.Import().shapes[0], 0)[2], {1, 1, 1});
}

TEST(GltfImporterTest, CubicSplineAndStepWeights) {
  MorphingSquare square;
  // CUBICSPLINE over 2 keys (0 s, 1 s): per key the in-tangents, values, out-tangents of
  // both targets; target 0 leaves 0 with a slope of 2 per second, target 1 stays 1.
  int spline = square.gltf.Floats({0, 0, 0, 1, 2, 0, /* key 1: */ 0, 0, 1, 1, 0, 0}, "SCALAR");
  square.gltf.Animate(square.node, "weights", square.gltf.Floats({0, 1}, "SCALAR"), spline, "CUBICSPLINE");
  Scene scene = square.gltf.Import();
  const AnimatedWeights& weights = scene.shapes[0].deformation->morph.weights;
  EXPECT_EQ(weights.interpolation(), Interpolation::kCubicSpline);
  ASSERT_EQ(weights.keys().size(), 2u);
  EXPECT_DOUBLE_EQ(weights.keys()[0].outTangent[0], 2.0 / 24);  // per second / fps
  // Half way (frame 12): h01(0.5) * 1 + h10(0.5) * (2 / 24 per frame) * 24 frames = 0.5 + 0.25.
  EXPECT_NEAR(weights.Evaluate(12)[0], 0.75, 1e-12);
  EXPECT_EQ(weights.Evaluate(12)[1], 1.0);
  ExpectNear(WorldVertices(scene.shapes[0], 12)[1], {1, 0, -0.25}, 1e-12);
  ExpectDeformedRoundTrip(scene, {0, 5, 12, 24});

  MorphingSquare stepped;
  stepped.gltf.Animate(stepped.node, "weights", stepped.times, stepped.gltf.Floats({0, 0, 1, 0, 0, 1}, "SCALAR"),
                       "STEP");
  Scene step = stepped.gltf.Import();
  EXPECT_EQ(step.shapes[0].deformation->morph.weights.Evaluate(11.9), (std::vector<double>{0, 0}));
  EXPECT_EQ(step.shapes[0].deformation->morph.weights.Evaluate(12), (std::vector<double>{1, 0}));
  ExpectDeformedRoundTrip(step, {0, 12, 24});
}

TEST(GltfImporterTest, SparseAccessorsAreResolved) {
  MorphingSquare square;
  // Target 0 as a sparse accessor without a buffer view: zeros but for vertices 1 and 2.
  json& accessors = square.gltf.doc()["accessors"];
  int indices = square.gltf.Integers({1, 2}, 5123, "SCALAR");
  int values = square.gltf.Floats({0, 0, 3, 0, 0, 4}, "VEC3");
  auto viewOf = [&](int accessor) { return accessors[accessor]["bufferView"]; };
  accessors[square.right] = {
      {"componentType", 5126},
      {"type", "VEC3"},
      {"count", 4},
      {"sparse",
       {{"count", 2},
        {"indices", {{"bufferView", viewOf(indices)}, {"componentType", 5123}}},
        {"values", {{"bufferView", viewOf(values)}}}}}};
  // Target 1 over its buffer view, with vertex 2's delta replaced by the second value.
  accessors[square.top]["sparse"] = {
      {"count", 1},
      {"indices", {{"bufferView", viewOf(indices)}, {"byteOffset", 2}, {"componentType", 5123}}},
      {"values", {{"bufferView", viewOf(values)}, {"byteOffset", 12}}}};
  square.gltf.doc()["meshes"][0]["weights"] = {1, 1};
  Scene scene = square.gltf.Import();
  const MorphTargets& morph = scene.shapes[0].deformation->morph;
  ExpectNear(morph.positionDeltas[0][0], {0, 0, 0}, 0);
  ExpectNear(morph.positionDeltas[0][1], {0, 0, 3}, 0);
  ExpectNear(morph.positionDeltas[0][2], {0, 0, 4}, 0);
  ExpectNear(morph.positionDeltas[1][2], {0, 0, 4}, 0);
  ExpectNear(morph.positionDeltas[1][3], {0, 0, 2}, 0);  // as its buffer view has it

  // Without a buffer view, no more zeros than the file's buffers could have held.
  accessors[square.right]["count"] = 100000;
  std::string what = ErrorOf([&] { square.gltf.Import(); });
  EXPECT_NE(what.find("scene/accessors/" + std::to_string(square.right) +
                      "/count: the gltf scene: 100000 elements without a buffer view (1200000 bytes of zeros)"),
            std::string::npos)
      << what;
  accessors[square.right]["count"] = 4;

  accessors[square.right]["sparse"]["count"] = 5;
  what = ErrorOf([&] { square.gltf.Import(); });
  EXPECT_NE(what.find("scene/accessors/" + std::to_string(square.right) +
                      "/sparse/count: the gltf scene: 5 substitutions in an accessor of 4 elements"),
            std::string::npos)
      << what;
  accessors[square.right]["sparse"]["count"] = 2;
  accessors[square.top]["sparse"]["indices"]["byteOffset"] = 0;
  accessors[square.top]["sparse"]["count"] = 2;
  accessors[square.top]["sparse"]["values"]["byteOffset"] = 0;
  // Indices 1, 2 read as bytes: 1, 0 (not increasing).
  accessors[square.top]["sparse"]["indices"]["componentType"] = 5121;
  what = ErrorOf([&] { square.gltf.Import(); });
  EXPECT_NE(what.find("scene/accessors/" + std::to_string(square.top) +
                      "/sparse/indices: the gltf scene: substitution 1 names element 0, not after the one before it"),
            std::string::npos)
      << what;
  accessors[square.top]["sparse"]["indices"]["componentType"] = 5123;
  accessors[square.top]["sparse"]["values"]["byteOffset"] = 16;  // 2 VEC3s from byte 16 of a 24-byte view
  what = ErrorOf([&] { square.gltf.Import(); });
  EXPECT_NE(what.find("scene/accessors/" + std::to_string(square.top) +
                      "/sparse/values: the gltf scene: 2 elements from byte 16 run past the end of buffer view"),
            std::string::npos)
      << what;
}

TEST(GltfImporterTest, BadMorphTargetsAreRefusedWithTheirPointers) {
  ExpectRefusals<MorphingSquare>({
      {[](MorphingSquare& m) { m.gltf.doc()["meshes"][0]["primitives"][1]["targets"].erase(1); },
       [](const MorphingSquare&) {
         return "scene/meshes/0/primitives/1/targets: the gltf scene: 1 morph targets where primitive 0 has 2";
       }},
      {[](MorphingSquare& m) { m.gltf.doc()["meshes"][0]["weights"] = {0.5}; },
       [](const MorphingSquare&) {
         return "scene/meshes/0/weights: the gltf scene: 1 weights for 2 morph targets; expected one weight per "
                "morph target";
       }},
      {[](MorphingSquare& m) { m.gltf.doc()["nodes"][0]["weights"] = {0.5, 0.5, 0.5}; },
       [](const MorphingSquare&) { return "scene/nodes/0/weights: the gltf scene: 3 weights for 2 morph targets"; }},
      {[](MorphingSquare& m) {
         m.gltf.Animate(m.node, "weights", m.times, m.gltf.Floats({0, 1, 0}, "SCALAR"));
       },
       [](const MorphingSquare&) {
         return "/count: the gltf scene: 3 values for 3 key times; expected 6 values (2 weights (one per morph "
                "target) per key)";
       }},
      {[](MorphingSquare& m) {
         int other = m.gltf.Node({{"mesh", m.gltf.Mesh(kTriangle)}}, true);
         m.gltf.Animate(other, "weights", m.times, m.gltf.Floats({0, 1, 0}, "SCALAR"));
       },
       [](const MorphingSquare&) {
         return "scene/animations/0/channels/0/target/node: the gltf scene: node 1 has no mesh with morph targets";
       }},
      {[](MorphingSquare& m) { m.gltf.doc()["accessors"][m.top]["count"] = 3; },
       [](const MorphingSquare& m) {
         return "scene/accessors/" + std::to_string(m.top) +
                "/count: the gltf scene: 3 position deltas for a primitive of 4 vertices";
       }},
  });
}

// Debian's assimp-testmodels: a skin and a morph that nobody in the project wrote. A
// model of one shape, imported; none when the package is not installed.
std::optional<Scene> ImportOneShapeTestModel(const std::string& relative) {
  const fs::path path = kTestModels / relative;
  if (!fs::exists(path)) return std::nullopt;
  Scene scene = ImportScene(path);
  EXPECT_EQ(scene.shapes.size(), 1u);
  return scene;
}

TEST(GltfImporterTest, SimpleSkinBendsAsItsFileSays) {
  const std::optional<Scene> model = ImportOneShapeTestModel("simple_skin/simple_skin.gltf");
  TCFARM_REQUIRE_TOOL(model, "assimp-testmodels is not installed (scripts/bootstrap)");
  const Scene& scene = *model;
  ASSERT_EQ(scene.shapes.size(), 1u);
  const Shape& shape = scene.shapes[0];
  ASSERT_TRUE(shape.deformation && shape.deformation->hasSkin);
  EXPECT_TRUE(shape.Deforms());
  EXPECT_EQ(scene.render.frameCount, 133);  // 5.5 s at 24 per second
  // Both inverse binds are T(-0.5, -1, 0); joint 0 is node 1 at (0, 1, 0), joint 1 its child,
  // turned about z by the quaternion (0, 0, 0.707, 0.707) at 1 s: a quarter turn.
  const std::vector<Vec3> rest = WorldVertices(shape, 0), bent = WorldVertices(shape, 24);
  ExpectNear(rest[4], {-0.5, 1, 0});  // (0, 1, 0) moved by T(0, 1, 0) T(-0.5, -1, 0)
  ExpectNear(rest[9], {0.5, 2, 0});
  // Vertex 9 (1, 2, 0), all joint 1: (0.5, 1, 0) turned to (-1, 0.5, 0), then up 1.
  ExpectNear(bent[9], {-1, 1.5, 0}, 1e-6);
  // Vertex 4 (0, 1, 0), half and half: (-0.5, 1, 0) and (0, -0.5, 0) + (0, 1, 0).
  ExpectNear(bent[4], {-0.25, 0.75, 0}, 1e-6);
  ExpectNear(bent[0], rest[0]);  // all joint 0, which stands still
  ExpectDeformedRoundTrip(scene, {0, 5, 24, 100});
}

TEST(GltfImporterTest, AnimatedMorphCubeMorphsAsItsFileSays) {
  const std::optional<Scene> model =
      ImportOneShapeTestModel("glTF-Sample-Models/AnimatedMorphCube-glTF/AnimatedMorphCube.gltf");
  TCFARM_REQUIRE_TOOL(model, "assimp-testmodels is not installed (scripts/bootstrap)");
  const Scene& scene = *model;
  ASSERT_EQ(scene.shapes.size(), 1u);
  const Shape& shape = scene.shapes[0];
  ASSERT_TRUE(shape.deformation && shape.deformation->hasMorph);
  EXPECT_TRUE(shape.Deforms());
  EXPECT_EQ(shape.deformation->morph.TargetCount(), 2u);
  EXPECT_EQ(shape.deformation->morph.weights.keys().size(), 127u);
  // Key 60 of the weights channel, at 1.9999994 s: weights 0.8055561 and 0.1944439 (from
  // AnimatedMorphCube.bin). Vertex 5's y: -0.01 + w0 * 0.0189325 + w1 * 0.0198908.
  const double frame = static_cast<double>(1.9999994039535522f) * 24;
  const double y = -0.01000000536441803 + 0.8055561184883118 * 0.018932528793811798 +
                   0.19444391131401062 * 0.019890835508704185;
  const DeformedVertices morphed = Deform(shape.Mesh(), *shape.deformation, frame);
  ExpectNear(morphed.positions[5], {-0.00999999325722456, y, -0.009999999776482582}, 1e-9);
  ExpectNear(morphed.positions[4], shape.Mesh().vertices[4], 0);  // no target moves it
  ExpectNear(Deform(shape.Mesh(), *shape.deformation, 0).positions[5], shape.Mesh().vertices[5], 0);
  EXPECT_FALSE(shape.deformation->SameAt(0, frame));
  ExpectDeformedRoundTrip(scene, {0, 30, frame});
}

}  // namespace
}  // namespace tcfarm
