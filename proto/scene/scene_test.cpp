#include "proto/scene/scene.h"
#include "proto/scene/shapes/shape_format.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include <unistd.h>

namespace tcfarm {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

json MinimalScene() {
  return json{{"camera", {{"position", {0, 0, 5}}, {"look_at", {0, 0, 0}}}},
              {"render", {{"width", 4}, {"height", 3}}}};
}

json WithShape(json shape) {
  json scene = MinimalScene();
  scene["shapes"] = json::array({std::move(shape)});
  return scene;
}

json Sphere() { return json{{"type", "sphere"}, {"center", {0, 0, 0}}, {"radius", 1}}; }

json Triangle() {
  return json{{"type", "mesh"}, {"vertices", {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}}, {"triangles", {{0, 1, 2}}}};
}

// Passes when parsing throws a SceneError at exactly `pointer` whose text says what was
// expected and mentions `mention`.
testing::AssertionResult FailsAt(const std::string& text, const std::string& pointer, const std::string& mention,
                                 const std::optional<fs::path>& base = std::nullopt) {
  try {
    ParseScene(text, base);
  } catch (const SceneError& error) {
    std::string what = error.what();
    if (error.pointer() != pointer) {
      return testing::AssertionFailure() << "pointer \"" << error.pointer() << "\" != \"" << pointer << "\": " << what;
    }
    if (what.rfind("scene" + pointer + ": ", 0) != 0 || what.find("; expected ") == std::string::npos) {
      return testing::AssertionFailure() << "badly formed message: " << what;
    }
    if (what.find(mention) == std::string::npos) {
      return testing::AssertionFailure() << "\"" << what << "\" does not mention \"" << mention << "\"";
    }
    return testing::AssertionSuccess();
  }
  return testing::AssertionFailure() << "no SceneError for " << text;
}

testing::AssertionResult FailsAt(const json& scene, const std::string& pointer, const std::string& mention) {
  return FailsAt(scene.dump(), pointer, mention);
}

// A fresh folder per test, removed afterwards.
class TempFolder {
 public:
  TempFolder() {
    static std::atomic<int> counter{0};
    path_ = fs::temp_directory_path() /
            ("tcfarm_scene_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::create_directories(path_);
  }
  ~TempFolder() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  const fs::path& path() const { return path_; }
  void Write(const fs::path& relative, const std::string& text) const {
    fs::create_directories((path_ / relative).parent_path());
    std::ofstream(path_ / relative, std::ios::binary) << text;
  }

 private:
  fs::path path_;
};

// Scenes the parser must accept (tests/scenes/valid), mesh files beside them.
const fs::path kValidScenes = "tests/scenes/valid";

std::string ReadText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// --- messages ---------------------------------------------------------------------

TEST(SceneErrorTest, MessageNamesPointerProblemAndExpectation) {
  json scene = MinimalScene();
  scene["shapes"] = json::array({Sphere(), Sphere(), Sphere(), Sphere()});
  scene["shapes"][3]["radius"] = -1;
  try {
    ParseScene(scene.dump());
    FAIL() << "no error";
  } catch (const SceneError& error) {
    EXPECT_EQ(error.pointer(), "/shapes/3/radius");
    EXPECT_STREQ(error.what(), "scene/shapes/3/radius: -1 is negative; expected a positive finite number");
  }
}

// --- bad input, shared with the schema ---------------------------------------------------

// tests/scenes/invalid/*.json hold the bad-input cases; tests/schema/test_scene_schema.py
// checks that the schema refuses each too (or, for the cases marked "parser_only", that
// it cannot). Cases needing files (OBJ references) stay in the tests below.
TEST(SceneInvalidCasesTest, ParserRefusesEachCaseAtItsPointer) {
  size_t count = 0;
  for (const auto& entry : fs::directory_iterator("tests/scenes/invalid")) {
    if (entry.path().extension() != ".json") continue;
    json file = json::parse(ReadText(entry.path()));
    for (const json& c : file.at("cases")) {
      std::string text = c.contains("text") ? c.at("text").get<std::string>() : c.at("scene").dump();
      EXPECT_TRUE(FailsAt(text, c.at("pointer").get<std::string>(), c.at("mention").get<std::string>()))
          << entry.path().filename().string() << ": " << c.at("name").get<std::string>();
      ++count;
    }
  }
  EXPECT_GE(count, 99u);  // the folder was found and read
}

// tests/scenes/valid/*.json: scenes at the edge of what is accepted (many are the
// accepted twins of an invalid case); the schema test validates them too.
TEST(SceneValidCasesTest, ParserAcceptsEachScene) {
  size_t count = 0;
  for (const auto& entry : fs::directory_iterator(kValidScenes)) {
    if (entry.path().extension() != ".json") continue;
    EXPECT_NO_THROW(ParseScene(ReadText(entry.path()), kValidScenes)) << entry.path().filename().string();
    ++count;
  }
  EXPECT_GE(count, 12u);
}

TEST(SceneValidCasesTest, IntegralNumberIsAnInteger) {
  // As in JSON Schema, 640.0 is an integer.
  Scene scene = ParseScene(ReadText(kValidScenes / "integral_float_width.json"));
  EXPECT_EQ(scene.render.width, 640);
}

// --- animated values --------------------------------------------------------------------

TEST(AnimatedVec3Test, PolynomialEvaluatesPerAxis) {
  AnimatedVec3 v = AnimatedVec3::Polynomial({{{1, 2, 3}, {-4}, {5, 0, 0, 1}}});
  EXPECT_EQ(v.Evaluate(2), (Vec3{17, -4, 13}));
  EXPECT_EQ(v.Evaluate(-1), (Vec3{2, -4, 4}));
  EXPECT_EQ(v.Evaluate(0), (Vec3{1, -4, 5}));
}

TEST(AnimatedVec3Test, KeyframesInterpolateAndHold) {
  AnimatedVec3 v = AnimatedVec3::Keyframes({{0, {0, 0, 7}}, {10, {10, 20, 7}}, {20, {10, 0, 7}}});
  EXPECT_EQ(v.Evaluate(-5), (Vec3{0, 0, 7}));
  EXPECT_EQ(v.Evaluate(0), (Vec3{0, 0, 7}));
  EXPECT_EQ(v.Evaluate(5), (Vec3{5, 10, 7}));
  EXPECT_EQ(v.Evaluate(10), (Vec3{10, 20, 7}));
  EXPECT_EQ(v.Evaluate(15), (Vec3{10, 10, 7}));
  EXPECT_EQ(v.Evaluate(20), (Vec3{10, 0, 7}));
  EXPECT_EQ(v.Evaluate(100), (Vec3{10, 0, 7}));
  EXPECT_TRUE(v.SameAt(-5, 0));
  EXPECT_FALSE(v.SameAt(0, 1));
}

TEST(AnimatedVec3Test, SingleKeyIsConstant) {
  AnimatedVec3 v = AnimatedVec3::Keyframes({{3, {1, 2, 3}}});
  EXPECT_EQ(v.Evaluate(-100), (Vec3{1, 2, 3}));
  EXPECT_EQ(v.Evaluate(100), (Vec3{1, 2, 3}));
  EXPECT_FALSE(v.IsAnimated());
}

TEST(AnimatedVec3Test, IsAnimated) {
  EXPECT_FALSE(AnimatedVec3().IsAnimated());
  EXPECT_FALSE(AnimatedVec3::Constant({1, 2, 3}).IsAnimated());
  EXPECT_FALSE(AnimatedVec3::Polynomial({{{5}, {1, 0}, {2, 0, 0}}}).IsAnimated());
  EXPECT_TRUE(AnimatedVec3::Polynomial({{{5}, {1, 0}, {2, 0, 1e-300}}}).IsAnimated());
  EXPECT_FALSE(AnimatedVec3::Keyframes({{0, {1, 1, 1}}, {9, {1, 1, 1}}}).IsAnimated());
  EXPECT_TRUE(AnimatedVec3::Keyframes({{0, {1, 1, 1}}, {9, {1, 1, 1}}, {12, {1, 2, 1}}}).IsAnimated());
}

TEST(AnimatedVec3Test, ParsedForms) {
  json scene = MinimalScene();
  scene["camera"]["position"] = {{"polynomial", {{0, 1}, {2}, {5, 0, 0.5}}}};
  scene["camera"]["look_at"] = {
      {"keyframes", {{{"frame", 0}, {"value", {0, 0, 0}}}, {{"frame", 4}, {"value", {4, 0, 0}}}}}};
  scene["render"]["frames"] = {{"start", 0}, {"count", 3}};
  Scene parsed = ParseScene(scene.dump());
  EXPECT_EQ(parsed.camera.position.kind(), AnimatedVec3::Kind::kPolynomial);
  EXPECT_EQ(parsed.camera.position.Evaluate(2), (Vec3{2, 2, 7}));
  EXPECT_EQ(parsed.camera.lookAt.Evaluate(1), (Vec3{1, 0, 0}));
  EXPECT_TRUE(parsed.CameraMoves());
}

// --- shapes ------------------------------------------------------------------------------

TEST(SceneShapeTest, MeshNormalsAndUvs) {
  json mesh = Triangle();
  mesh["normals"] = {{0, 0, 1}, {0, 0.6, 0.8}, {0, 0, 0}};
  mesh["uvs"] = {{0, 0}, {1, 0}, {0, 1}};
  Scene parsed = ParseScene(WithShape(mesh).dump());
  EXPECT_EQ(parsed.shapes[0].mesh.normals[1], (Vec3{0, 0.6, 0.8}));
  EXPECT_EQ(parsed.shapes[0].mesh.uvs[2], (std::array<double, 2>{0, 1}));
  json written = json::parse(SerializeScene(parsed));
  EXPECT_EQ(written["shapes"][0]["normals"], mesh["normals"]);
  EXPECT_EQ(written["shapes"][0]["uvs"], mesh["uvs"]);
  // Without them nothing is written: older scenes serialise to the same bytes as before.
  EXPECT_FALSE(json::parse(SerializeScene(ParseScene(WithShape(Triangle()).dump())))["shapes"][0].contains("normals"));

}

TEST(SceneShapeTest, MeshVertexColoursRoundTripAndAreChecked) {
  json mesh = Triangle();
  mesh["colors"] = {{1, 0, 0}, {0, 0.5, 0}, {0, 0, 2}};
  Scene parsed = ParseScene(WithShape(mesh).dump());
  EXPECT_EQ(parsed.shapes[0].mesh.colors[1], (Vec3{0, 0.5, 0}));
  json written = json::parse(SerializeScene(parsed));
  EXPECT_EQ(written["shapes"][0]["colors"], mesh["colors"]);
  EXPECT_FALSE(json::parse(SerializeScene(ParseScene(WithShape(Triangle()).dump())))["shapes"][0].contains("colors"));

  json negative = mesh;
  negative["colors"][2] = {0, -1, 0};
  EXPECT_TRUE(FailsAt(WithShape(negative), "/shapes/0/colors/2/1", "non-negative"));
  json short_ = mesh;
  short_["colors"].erase(2);
  EXPECT_TRUE(FailsAt(WithShape(short_), "/shapes/0/colors", "colour"));
  json withFile = json{{"type", "mesh"}, {"file", "x.obj"}, {"colors", mesh["colors"]}};
  EXPECT_TRUE(FailsAt(WithShape(withFile), "/shapes/0/file", "both a file and inline geometry"));
}

TEST(SceneShapeTest, MotionAppliesToEveryType) {
  json scene = MinimalScene();
  json motion = {{"polynomial", {{0, 1}, {0}, {0}}}};
  json terrain{{"type", "terrain"}, {"origin", {0, 0, 0}}, {"size", {1, 1}}, {"cells", {1, 1}}};
  json quad{{"type", "quad"}, {"corner", {0, 0, 0}}, {"edge_u", {1, 0, 0}}, {"edge_v", {0, 1, 0}}};
  scene["shapes"] = {Sphere(), quad, Triangle(), terrain};
  for (auto& shape : scene["shapes"]) shape["motion"] = motion;
  Scene parsed = ParseScene(scene.dump());
  for (const Shape& shape : parsed.shapes) EXPECT_TRUE(shape.Moves());
  EXPECT_TRUE(parsed.AnyShapeMoves());
}

// The table of kinds: each found by its JSON name, all of them named where a type is wrong.
TEST(SceneShapeTest, EveryKindIsFoundByItsNameAndNamedInMessages) {
  for (size_t i = 0; i < Shape::kTypeCount; ++i) {
    const auto type = static_cast<Shape::Type>(i);
    EXPECT_EQ(FindShapeType(FormatOf(type).Name()), type) << FormatOf(type).Name();
  }
  EXPECT_EQ(FindShapeType("cone"), std::nullopt);
  EXPECT_TRUE(FailsAt(WithShape({{"type", "cone"}}).dump(), "/shapes/0/type",
                      "unknown shape type \"cone\"; expected \"sphere\", \"quad\", \"mesh\" or \"terrain\""));
}

// --- materials ---------------------------------------------------------------------------

TEST(SceneMaterialTest, DefaultFirstThenSortedByName) {
  json scene = WithShape(Sphere());
  scene["materials"] = {{"zeta", {{"reflectivity", 0.5}}}, {"alpha", {{"transparency", 0.25}}}};
  scene["shapes"][0]["material"] = "zeta";
  Scene parsed = ParseScene(scene.dump());
  ASSERT_EQ(parsed.materials.size(), 3u);
  EXPECT_EQ(parsed.materials[0].name, "default");
  EXPECT_EQ(parsed.materials[1].name, "alpha");
  EXPECT_EQ(parsed.materials[2].name, "zeta");
  EXPECT_EQ(parsed.shapes[0].material, 2);
  EXPECT_TRUE(parsed.AnyMaterialReflects());
  EXPECT_TRUE(parsed.AnyMaterialRefracts());
}

TEST(SceneMaterialTest, UserDefaultReplacesBuiltIn) {
  json scene = WithShape(Sphere());
  scene["materials"] = {{"default", {{"diffuse", {0.1, 0.2, 0.3}}}}};
  Scene parsed = ParseScene(scene.dump());
  ASSERT_EQ(parsed.materials.size(), 1u);
  EXPECT_EQ(parsed.materials[0].As<Phong>().diffuse, (Vec3{0.1, 0.2, 0.3}));
  EXPECT_EQ(parsed.shapes[0].material, 0);
}

// A material names one model's keys: Phong's, or a "pbr" block, never both.
TEST(SceneMaterialTest, KeysPickTheModelAndTwoModelsAreRefused) {
  json scene = WithShape(Sphere());
  scene["materials"] = {{"plain", json::object()}, {"metal", {{"pbr", {{"metallic", 1}}}}}};
  Scene parsed = ParseScene(scene.dump());
  EXPECT_TRUE(parsed.materials[2].Is<Phong>());  // "plain": no model's keys, the first model
  ASSERT_TRUE(parsed.materials[1].Is<MetallicRoughness>());
  EXPECT_EQ(parsed.materials[1].As<MetallicRoughness>().metallic, 1);
  scene["materials"] = {{"both", {{"pbr", json::object()}, {"specular", {1, 1, 1}}, {"shininess", 8}}}};
  EXPECT_TRUE(FailsAt(scene, "/materials/both/specular", "a Phong parameter beside a \"pbr\" block"));
}

// --- defaults ----------------------------------------------------------------------------

TEST(SceneDefaultsTest, MinimalScene) {
  Scene scene = ParseScene(MinimalScene().dump());
  EXPECT_EQ(scene.camera.up, (Vec3{0, 1, 0}));
  EXPECT_EQ(scene.camera.verticalFovDegrees, 45);
  EXPECT_TRUE(scene.lights.empty());
  EXPECT_TRUE(scene.shapes.empty());
  ASSERT_EQ(scene.materials.size(), 1u);
  EXPECT_EQ(scene.materials[0].name, "default");
  EXPECT_EQ(scene.materials[0].As<Phong>().diffuse, (Vec3{0.8, 0.8, 0.8}));
  EXPECT_EQ(scene.background, (Vec3{0, 0, 0}));
  EXPECT_EQ(scene.render.width, 4);
  EXPECT_EQ(scene.render.height, 3);
  EXPECT_EQ(scene.render.firstFrame, 0);
  EXPECT_EQ(scene.render.frameCount, 1);
  EXPECT_EQ(scene.render.samplesPerPixel, 1);
  EXPECT_EQ(scene.render.maxDepth, 5);
  EXPECT_FALSE(scene.CameraMoves());
  EXPECT_FALSE(scene.AnyLightChanges());
  EXPECT_FALSE(scene.AnyShapeMoves());
  EXPECT_FALSE(scene.AnyMaterialReflects());
  EXPECT_FALSE(scene.AnyMaterialRefracts());
}

TEST(SceneDefaultsTest, MaterialShapeAndTerrainDefaults) {
  json scene = MinimalScene();
  scene["materials"] = {{"plain", json::object()}};
  scene["shapes"] = {Sphere(), {{"type", "terrain"}, {"origin", {0, 0, 0}}, {"size", {10, 20}}}};
  scene["render"]["frames"] = {{"start", 7}};
  Scene parsed = ParseScene(scene.dump());
  const Material& plain = parsed.materials.at(1);
  EXPECT_EQ(plain.As<Phong>().diffuse, (Vec3{0.8, 0.8, 0.8}));
  EXPECT_EQ(plain.As<Phong>().specular, (Vec3{0, 0, 0}));
  EXPECT_EQ(plain.As<Phong>().shininess, 32);
  EXPECT_EQ(plain.As<Phong>().reflectivity, 0);
  EXPECT_EQ(plain.As<Phong>().transparency, 0);
  EXPECT_EQ(plain.As<Phong>().indexOfRefraction, 1.5);
  const Shape& sphere = parsed.shapes[0];
  EXPECT_EQ(sphere.material, 0);
  EXPECT_EQ(sphere.motion.translation.kind(), AnimatedVec3::Kind::kConstant);
  EXPECT_EQ(sphere.motion.translation.Evaluate(3), (Vec3{0, 0, 0}));
  const Shape& terrain = parsed.shapes[1];
  EXPECT_EQ(terrain.terrain.cellsX, 100);
  EXPECT_EQ(terrain.terrain.cellsZ, 100);
  EXPECT_EQ(terrain.terrain.seed, 1u);
  EXPECT_EQ(terrain.terrain.height, 1);
  EXPECT_EQ(terrain.mesh.triangles.size(), 20000u);
  EXPECT_EQ(parsed.render.firstFrame, 7);
  EXPECT_EQ(parsed.render.frameCount, 1);
}

TEST(ScenePredicateTest, LightChanges) {
  json scene = MinimalScene();
  scene["lights"] = {{{"type", "point"}, {"position", {0, 5, 0}}, {"intensity", {1, 1, 1}}}};
  EXPECT_FALSE(ParseScene(scene.dump()).AnyLightChanges());
  scene["lights"][0]["intensity"] = {{"polynomial", {{1, 0.1}, {1}, {1}}}};
  EXPECT_TRUE(ParseScene(scene.dump()).AnyLightChanges());
}

// --- terrain -----------------------------------------------------------------------------

Shape::Terrain SampleTerrain() {
  Shape::Terrain terrain;
  terrain.origin = {-50, 2, -50};
  terrain.sizeX = 100;
  terrain.sizeZ = 100;
  terrain.height = 8;
  terrain.seed = 7;
  return terrain;
}

TEST(TerrainTest, GridSize) {
  TriangleMesh mesh = GenerateTerrain(SampleTerrain());
  EXPECT_EQ(mesh.triangles.size(), 20000u);
  EXPECT_EQ(mesh.vertices.size(), 101u * 101u);
  Shape::Terrain narrow = SampleTerrain();
  narrow.cellsX = 3;
  narrow.cellsZ = 5;
  EXPECT_EQ(GenerateTerrain(narrow).triangles.size(), 30u);
}

TEST(TerrainTest, Deterministic) {
  TriangleMesh a = GenerateTerrain(SampleTerrain());
  TriangleMesh b = GenerateTerrain(SampleTerrain());
  ASSERT_EQ(a.vertices.size(), b.vertices.size());
  EXPECT_EQ(0, std::memcmp(a.vertices.data(), b.vertices.data(), a.vertices.size() * sizeof(Vec3)));
  EXPECT_EQ(a.triangles, b.triangles);
}

TEST(TerrainTest, SeedChangesHeights) {
  Shape::Terrain other = SampleTerrain();
  other.seed = 8;
  TriangleMesh a = GenerateTerrain(SampleTerrain());
  TriangleMesh b = GenerateTerrain(other);
  size_t differing = 0;
  for (size_t i = 0; i < a.vertices.size(); ++i) differing += a.vertices[i].y != b.vertices[i].y;
  EXPECT_GT(differing, a.vertices.size() * 9 / 10);
}

TEST(TerrainTest, CoversItsRectangleWithinItsHeight) {
  Shape::Terrain terrain = SampleTerrain();
  TriangleMesh mesh = GenerateTerrain(terrain);
  EXPECT_EQ(mesh.vertices.front().x, -50);
  EXPECT_EQ(mesh.vertices.front().z, -50);
  EXPECT_EQ(mesh.vertices.back().x, 50);
  EXPECT_EQ(mesh.vertices.back().z, 50);
  double low = 1e9, high = -1e9;
  for (const Vec3& v : mesh.vertices) {
    low = std::min(low, v.y);
    high = std::max(high, v.y);
  }
  EXPECT_GE(low, 2);
  EXPECT_LE(high, 10);
  EXPECT_GT(high - low, 2);  // hills, not a plane
}

TEST(TerrainTest, NormalsPointUp) {
  TriangleMesh mesh = GenerateTerrain(SampleTerrain());
  for (const auto& t : mesh.triangles) {
    const Vec3& a = mesh.vertices[t[0]];
    const Vec3& b = mesh.vertices[t[1]];
    const Vec3& c = mesh.vertices[t[2]];
    Vec3 ab{b.x - a.x, b.y - a.y, b.z - a.z};
    Vec3 ac{c.x - a.x, c.y - a.y, c.z - a.z};
    double normalY = ab.z * ac.x - ab.x * ac.z;
    ASSERT_GT(normalY, 0);
  }
}

// Guards the "same bits everywhere" promise against accidental changes to the noise:
// a change here changes every rendered terrain, so it must be deliberate.
TEST(TerrainTest, GoldenHeights) {
  Shape::Terrain terrain = SampleTerrain();
  terrain.cellsX = 4;
  terrain.cellsZ = 4;
  TriangleMesh mesh = GenerateTerrain(terrain);
  uint64_t hash = 1469598103934665603ULL;
  for (const Vec3& v : mesh.vertices) {
    for (int axis = 0; axis < 3; ++axis) {
      uint64_t bits;
      double value = v[axis];
      std::memcpy(&bits, &value, sizeof bits);
      hash = (hash ^ bits) * 1099511628211ULL;
    }
  }
  EXPECT_EQ(hash, 0xf4d7a6a5d50d45b8ULL) << std::hex << hash;
}

// --- OBJ files ---------------------------------------------------------------------------

json FileMesh(const std::string& file) { return json{{"type", "mesh"}, {"file", file}}; }

TEST(SceneObjTest, FanTriangulationAndIndexForms) {
  TempFolder folder;
  folder.Write("models/shape.obj",
               "# a square and a pentagon\r\n"
               "mtllib shape.mtl\n"
               "o square\n"
               "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
               "vt 0 0\nvn 0 0 1\n"
               "g top\ns off\nusemtl red\n"
               "f 1/1 2/1/1 3//1 4\n"
               "v 0 0 1\nv 1 0 1\nv 1.5 0.5 1\nv 1 1 1\nv 0 1 1 1.0\n"
               "f -5 -4 -3 -2 -1  # relative\n");
  Scene scene = ParseScene(WithShape(FileMesh("models/shape.obj")).dump(), folder.path());
  const TriangleMesh& mesh = scene.shapes[0].mesh;
  ASSERT_EQ(mesh.vertices.size(), 9u);
  EXPECT_EQ(mesh.vertices[6], (Vec3{1.5, 0.5, 1}));
  using T = std::array<uint32_t, 3>;
  std::vector<T> expected{T{0, 1, 2}, T{0, 2, 3}, T{4, 5, 6}, T{4, 6, 7}, T{4, 7, 8}};
  EXPECT_EQ(mesh.triangles, expected);
}

TEST(SceneObjTest, NormalsAndUvsOfAFileAreKept) {
  TempFolder folder;
  folder.Write("quad.obj",
               "mtllib absent.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
               "vn 0 0 1\nusemtl absent\nf 1/1/1 2/2/1 3/3/1 4/4/1\n");
  Scene scene = ParseScene(WithShape(FileMesh("quad.obj")).dump(), folder.path());
  const TriangleMesh& mesh = scene.shapes[0].mesh;
  ASSERT_EQ(mesh.normals.size(), 4u);
  ASSERT_EQ(mesh.uvs.size(), 4u);
  EXPECT_EQ(mesh.normals[2], (Vec3{0, 0, 1}));
  EXPECT_EQ(mesh.uvs[2], (std::array<double, 2>{1, 1}));
  EXPECT_EQ(scene.shapes[0].material, 0);  // the JSON shape's material, not the file's
  Scene reread = ParseScene(SerializeScene(scene));
  EXPECT_EQ(reread.shapes[0].mesh.normals, mesh.normals);
  EXPECT_EQ(reread.shapes[0].mesh.uvs, mesh.uvs);
}

TEST(SceneObjTest, ConcaveFaceIsClippedNotFanned) {
  TempFolder folder;
  folder.Write("l.obj", "v 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nf 2 3 4 5 6 1\n");
  Scene scene = ParseScene(WithShape(FileMesh("l.obj")).dump(), folder.path());
  EXPECT_EQ(scene.shapes[0].mesh.triangles.size(), 4u);
  for (const auto& t : scene.shapes[0].mesh.triangles) {
    // No triangle of the L spans its notch: none has corners (2, 0) and (1, 2) together.
    bool spansNotch = std::count(t.begin(), t.end(), 1u) == 1 && std::count(t.begin(), t.end(), 4u) == 1;
    EXPECT_FALSE(spansNotch);
  }
}

TEST(SceneObjTest, ObjTriangleBudget) {
  TempFolder folder;
  folder.Write("quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n");
  json terrain{{"type", "terrain"}, {"origin", {0, 0, 0}}, {"size", {10, 10}}, {"cells", {2000, 2000}}};
  json last{{"type", "terrain"}, {"origin", {0, 0, 0}}, {"size", {10, 10}}, {"cells", {1999, 1000}}};
  json scene = MinimalScene();
  // 8000000 + 8000000 + 3998000 leaves 2000 triangles: 1000 quads fit, the 1001st does not.
  // (Only the failing case: a scene that passes would generate 20 million triangles.)
  scene["shapes"] = {terrain, terrain, last, FileMesh("quad.obj")};
  std::string many = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";
  for (int i = 0; i < 1001; ++i) many += "f 1 2 3 4\n";
  folder.Write("quad.obj", many);
  EXPECT_TRUE(FailsAt(scene.dump(), "/shapes/3/file", "quad.obj line 1005: the scene exceeds 20000000 triangles",
                      folder.path()));
}

TEST(SceneObjTest, WithoutBaseDirectoryFilesAreRejected) {
  EXPECT_TRUE(FailsAt(WithShape(FileMesh("models/shape.obj")), "/shapes/0/file", "must inline their meshes"));
}

TEST(SceneObjTest, AbsolutePathRejected) {
  TempFolder folder;
  folder.Write("tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  EXPECT_TRUE(FailsAt(WithShape(FileMesh((folder.path() / "tri.obj").string())).dump(), "/shapes/0/file", "absolute",
                      folder.path()));
}

TEST(SceneObjTest, DotDotEscapeRejected) {
  TempFolder folder;
  folder.Write("outside.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  fs::create_directories(folder.path() / "scene" / "models");
  EXPECT_TRUE(FailsAt(WithShape(FileMesh("models/../../outside.obj")).dump(), "/shapes/0/file",
                      "outside the scene folder", folder.path() / "scene"));
  // Going up and back down inside the folder is fine.
  folder.Write("scene/tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  EXPECT_NO_THROW(ParseScene(WithShape(FileMesh("models/../tri.obj")).dump(), folder.path() / "scene"));
}

TEST(SceneObjTest, SymlinkEscapeRejected) {
  TempFolder folder;
  folder.Write("outside.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  fs::create_directories(folder.path() / "scene");
  fs::create_symlink(folder.path() / "outside.obj", folder.path() / "scene" / "link.obj");
  fs::create_directory_symlink(folder.path(), folder.path() / "scene" / "up");
  EXPECT_TRUE(FailsAt(WithShape(FileMesh("link.obj")).dump(), "/shapes/0/file", "outside the scene folder",
                      folder.path() / "scene"));
  EXPECT_TRUE(FailsAt(WithShape(FileMesh("up/outside.obj")).dump(), "/shapes/0/file", "outside the scene folder",
                      folder.path() / "scene"));
}

TEST(SceneObjTest, MissingFile) {
  TempFolder folder;
  EXPECT_TRUE(FailsAt(WithShape(FileMesh("missing.obj")).dump(), "/shapes/0/file", "cannot read", folder.path()));
  fs::create_directories(folder.path() / "dir.obj");
  EXPECT_TRUE(FailsAt(WithShape(FileMesh("dir.obj")).dump(), "/shapes/0/file", "cannot read", folder.path()));
}

TEST(SceneObjTest, MalformedObjNamesTheLine) {
  TempFolder folder;
  const std::string header = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  auto failsWith = [&](const std::string& body, const std::string& mention) {
    folder.Write("bad.obj", header + body);
    return FailsAt(WithShape(FileMesh("bad.obj")).dump(), "/shapes/0/file", mention, folder.path());
  };
  EXPECT_TRUE(failsWith("f 1 2\n", "bad.obj line 4: a face with 2 vertices"));
  EXPECT_TRUE(failsWith("\nv 1 x 2\n", "line 5: bad coordinate \"x\""));
  EXPECT_TRUE(failsWith("v 1 2\n", "line 4"));
  EXPECT_TRUE(failsWith("f 1 2 4\n", "line 4: vertex reference 4"));
  EXPECT_TRUE(failsWith("f 1 2 -4\n", "line 4: vertex reference -4"));
  EXPECT_TRUE(failsWith("f 1 2 0\n", "line 4"));
  EXPECT_TRUE(failsWith("f 1 2 3/1/1/1\n", "line 4"));
  EXPECT_TRUE(failsWith("v 1 1e999 2\n", "line 4"));
  EXPECT_TRUE(failsWith("", "no triangles"));
  EXPECT_TRUE(failsWith("f 1 1 2\n", "zero area"));
}

TEST(SceneFileTest, LoadSceneFileResolvesMeshesNextToIt) {
  TempFolder folder;
  folder.Write("jobs/models/tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  folder.Write("jobs/scene.json", WithShape(FileMesh("models/tri.obj")).dump());
  Scene scene = LoadSceneFile(folder.path() / "jobs" / "scene.json");
  ASSERT_EQ(scene.shapes.size(), 1u);
  EXPECT_EQ(scene.shapes[0].mesh.triangles.size(), 1u);
  EXPECT_EQ(SerializeScene(scene).find("\"file\""), std::string::npos);
}

TEST(SceneFileTest, MissingSceneFile) {
  TempFolder folder;
  try {
    LoadSceneFile(folder.path() / "nope.json");
    FAIL() << "no error";
  } catch (const SceneError& error) {
    EXPECT_EQ(error.pointer(), "");
    EXPECT_NE(std::string(error.what()).find("expected a readable scene file"), std::string::npos);
  }
}

// --- serialisation -----------------------------------------------------------------------

// Every feature at once, with a mesh file beside it (tri.obj).
json EveryFeatureScene() { return json::parse(ReadText(kValidScenes / "every_feature.json")); }

TEST(SceneSerializeTest, RoundTripIsStable) {
  Scene original = ParseScene(EveryFeatureScene().dump(), kValidScenes);
  std::string first = SerializeScene(original);
  Scene reread = ParseScene(first);
  std::string second = SerializeScene(reread);
  EXPECT_EQ(first, second);

  EXPECT_EQ(reread.shapes[4].mesh.vertices, original.shapes[4].mesh.vertices);
  EXPECT_EQ(reread.shapes[5].type, Shape::Type::kTerrain);
  EXPECT_EQ(reread.shapes[5].terrain.seed, 18446744073709551615ULL);
  ASSERT_EQ(reread.shapes[5].mesh.vertices.size(), original.shapes[5].mesh.vertices.size());
  EXPECT_EQ(0, std::memcmp(reread.shapes[5].mesh.vertices.data(), original.shapes[5].mesh.vertices.data(),
                           original.shapes[5].mesh.vertices.size() * sizeof(Vec3)));
  EXPECT_EQ(reread.camera.position.Evaluate(7), original.camera.position.Evaluate(7));
  EXPECT_EQ(reread.shapes[0].motion.translation.Evaluate(5), original.shapes[0].motion.translation.Evaluate(5));
  EXPECT_EQ(reread.shapes[0].material, original.shapes[0].material);
  EXPECT_EQ(reread.materials[0].name, "default");

  // Terrain travels as parameters, not as 672 triangles.
  json written = json::parse(first);
  EXPECT_FALSE(written["shapes"][5].contains("vertices"));
  EXPECT_EQ(written["shapes"][5]["cells"], json({20, 16}));
}

TEST(SceneSerializeTest, PredicatesOfEveryFeatureScene) {
  Scene scene = ParseScene(EveryFeatureScene().dump(), kValidScenes);
  EXPECT_TRUE(scene.CameraMoves());
  EXPECT_TRUE(scene.AnyLightChanges());
  EXPECT_TRUE(scene.AnyShapeMoves());
  EXPECT_TRUE(scene.AnyMaterialReflects());
  EXPECT_TRUE(scene.AnyMaterialRefracts());
  EXPECT_FALSE(scene.shapes[1].Moves());
}

// Rebasing moves everything placed by the scene and nothing relative: the camera stands at
// the origin at the first frame, every other position keeps its offset from it, and
// motions (of camera, lights and shapes) stay as they are.
TEST(SceneRebaseTest, CameraStandsAtTheOriginAndMotionsStay) {
  Scene scene = ParseScene(R"({
    "camera": {"position": {"keyframes": [{"frame": 2, "value": [1e6, 5, 3]}, {"frame": 9, "value": [1e6, 5, 10]}]},
               "look_at": [1e6, 0, 0]},
    "lights": [{"type": "point", "position": {"polynomial": [[1e6, 1], [7], [1]]}, "intensity": [1, 1, 1]},
               {"type": "directional", "direction": [0, -1, 0], "intensity": [1, 1, 1]}],
    "shapes": [{"type": "sphere", "center": [1e6, 1, 1], "radius": 0.5, "motion": {"polynomial": [[0, 0.5], [0], [0]]}},
               {"type": "quad", "corner": [999990, 0, -5], "edge_u": [20, 0, 0], "edge_v": [0, 0, 10]},
               {"type": "mesh", "vertices": [[1e6, 2, 0], [1000001, 2, 0], [1e6, 3, 0]], "triangles": [[0, 1, 2]]}],
    "render": {"width": 4, "height": 4, "frames": {"start": 4, "count": 3}}
  })");
  const Scene before = scene;
  RebaseOnCamera(scene);
  const Vec3 camera = before.camera.position.Evaluate(4);
  auto moved = [&](const Vec3& v) { return Vec3{v.x - camera.x, v.y - camera.y, v.z - camera.z}; };
  EXPECT_EQ(scene.camera.position.Evaluate(4), (Vec3{0, 0, 0}));
  for (int frame : {2, 4, 6, 9}) {
    EXPECT_EQ(scene.camera.position.Evaluate(frame), moved(before.camera.position.Evaluate(frame))) << frame;
    EXPECT_EQ(scene.lights[0].position.Evaluate(frame), moved(before.lights[0].position.Evaluate(frame))) << frame;
  }
  EXPECT_EQ(scene.camera.lookAt.Evaluate(5), moved(before.camera.lookAt.Evaluate(5)));
  EXPECT_EQ(scene.lights[1].direction.Evaluate(5), before.lights[1].direction.Evaluate(5));
  EXPECT_EQ(scene.shapes[0].center, moved(before.shapes[0].center));
  EXPECT_EQ(scene.shapes[0].motion.translation.Evaluate(6), before.shapes[0].motion.translation.Evaluate(6));
  EXPECT_EQ(scene.shapes[1].corner, moved(before.shapes[1].corner));
  EXPECT_EQ(scene.shapes[1].edgeU, before.shapes[1].edgeU);
  EXPECT_EQ(scene.shapes[2].mesh.vertices[1], moved(before.shapes[2].mesh.vertices[1]));
  EXPECT_EQ(scene.CameraMoves(), before.CameraMoves());
  EXPECT_EQ(scene.AnyLightChanges(), before.AnyLightChanges());
}

// --- shared meshes ------------------------------------------------------------------

json SharedTriangleScene() {
  json scene = MinimalScene();
  json triangle = Triangle();
  triangle.erase("type");
  triangle["uvs"] = {{0, 0}, {1, 0}, {0, 1}};
  scene["meshes"] = {{"leaf", triangle}};
  scene["shapes"] = {{{"type", "mesh"}, {"mesh_ref", "leaf"}},
                     {{"type", "mesh"}, {"mesh_ref", "leaf"}, {"motion", {1, 0, 0}}}};
  return scene;
}

TEST(SharedMeshTest, PlacementsShareOneMesh) {
  Scene scene = ParseScene(SharedTriangleScene().dump());
  ASSERT_EQ(1u, scene.meshes.size());
  ASSERT_EQ(2u, scene.shapes.size());
  EXPECT_EQ("leaf", scene.shapes[1].meshRef);
  EXPECT_EQ(scene.shapes[0].sharedMesh, scene.shapes[1].sharedMesh);
  EXPECT_EQ(scene.meshes.at("leaf"), scene.shapes[0].sharedMesh);
  EXPECT_EQ(3u, scene.shapes[1].Mesh().vertices.size());
  EXPECT_TRUE(scene.shapes[1].mesh.vertices.empty());
}

TEST(SharedMeshTest, RoundTripWritesTheMeshOnce) {
  const std::string written = SerializeScene(ParseScene(SharedTriangleScene().dump()));
  EXPECT_EQ(written, SerializeScene(ParseScene(written)));
  json document = json::parse(written);
  EXPECT_EQ(3u, document["meshes"]["leaf"]["vertices"].size());
  EXPECT_EQ(json({{"type", "mesh"}, {"mesh_ref", "leaf"}, {"material", "default"}, {"motion", {1, 0, 0}}}),
            document["shapes"][1]);
  // The vertices appear once in the text, however many shapes place them.
  EXPECT_EQ(written.find("\"vertices\""), written.rfind("\"vertices\""));
}

TEST(SharedMeshTest, SceneWithoutSharedMeshesWritesNoTable) {
  const std::string written = SerializeScene(ParseScene(WithShape(Triangle()).dump()));
  EXPECT_EQ(std::string::npos, written.find("\"meshes\""));
  EXPECT_EQ(std::string::npos, written.find("mesh_ref"));
}

TEST(SharedMeshTest, BadReferencesNameTheirPointer) {
  json unknown = SharedTriangleScene();
  unknown["shapes"][1]["mesh_ref"] = "twig";
  EXPECT_TRUE(FailsAt(unknown, "/shapes/1/mesh_ref", "unknown mesh \"twig\""));
  json noTable = WithShape({{"type", "mesh"}, {"mesh_ref", "leaf"}});
  EXPECT_TRUE(FailsAt(noTable, "/shapes/0/mesh_ref", "unknown mesh"));
  json both = SharedTriangleScene();
  both["shapes"][0]["vertices"] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  EXPECT_TRUE(FailsAt(both, "/shapes/0/mesh_ref", "both a shared mesh and geometry"));
  json notText = SharedTriangleScene();
  notText["shapes"][0]["mesh_ref"] = 3;
  EXPECT_TRUE(FailsAt(notText, "/shapes/0/mesh_ref", "3"));
}

TEST(SharedMeshTest, EveryTableMeshIsCheckedUsedOrNot) {
  json unused = SharedTriangleScene();
  unused["meshes"]["twig"] = {{"vertices", {{0, 0, 0}, {1, 0, 0}}}, {"triangles", {{0, 1, 2}}}};
  EXPECT_TRUE(FailsAt(unused, "/meshes/twig/triangles/0/2", "out of range"));
  json flat = SharedTriangleScene();
  flat["meshes"]["twig"] = {{"vertices", {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}}}, {"triangles", {{0, 1, 2}}}};
  EXPECT_TRUE(FailsAt(flat, "/meshes/twig/triangles", "zero area"));
  json extra = SharedTriangleScene();
  extra["meshes"]["leaf"]["material"] = "default";
  EXPECT_TRUE(FailsAt(extra, "/meshes/leaf/material", "unknown"));
  json notObject = SharedTriangleScene();
  notObject["meshes"] = json::array();
  EXPECT_TRUE(FailsAt(notObject, "/meshes", "an object mapping mesh names"));
}

TEST(SharedMeshTest, RebasingAndPlacingMatchInlineCopies) {
  json shared = SharedTriangleScene();
  shared["camera"]["position"] = {3, 4, 5};
  shared["shapes"][0]["motion"] = {{"translation", {2, 0, 0}}, {"scale", {2, 1, 1}}};
  shared["shapes"][1]["motion"] = {{"polynomial", {{1, 0.5}, {0}, {0}}}};
  shared["render"]["frames"] = {{"start", 0}, {"count", 3}};
  json inlined = shared;
  for (json& shape : inlined["shapes"]) {
    shape.erase("mesh_ref");
    shape.update(shared["meshes"]["leaf"]);
  }
  inlined.erase("meshes");
  Scene a = ParseScene(shared.dump()), b = ParseScene(inlined.dump());
  PrepareForTracing(a);
  PrepareForTracing(b);
  for (size_t i = 0; i < a.shapes.size(); ++i) {
    EXPECT_EQ(b.shapes[i].Mesh().vertices, a.shapes[i].Mesh().vertices) << i;
  }
  // The still placement is built in place; the moving one still shares the moved mesh.
  EXPECT_FALSE(a.shapes[0].SharesMesh());
  EXPECT_EQ(a.meshes.at("leaf"), a.shapes[1].sharedMesh);
}

}  // namespace
}  // namespace tcfarm
