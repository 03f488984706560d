#include "tests/support/cpp/scene_test_support.h"
#include "proto/scene/import/scene_import.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <functional>
#include <fstream>
#include <string>

#include <unistd.h>

namespace tcfarm {
namespace {

namespace fs = std::filesystem;

class TempFolder {
 public:
  TempFolder() {
    static std::atomic<int> counter{0};
    path_ = fs::temp_directory_path() /
            ("tcfarm_import_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::create_directories(path_);
  }
  ~TempFolder() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  const fs::path& path() const { return path_; }
  fs::path Write(const fs::path& relative, const std::string& text) const {
    fs::create_directories((path_ / relative).parent_path());
    std::ofstream(path_ / relative, std::ios::binary) << text;
    return path_ / relative;
  }

 private:
  fs::path path_;
};

constexpr double kPi = 3.14159265358979323846;

const char* const kJsonScene = R"({"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
  "render": {"width": 4, "height": 3}, "shapes": [{"type": "mesh", "file": "tri.obj"}]})";
const char* const kTriangle = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

// Two quads of a unit box's corner, a red one and a mirror one, and a triangle with no usemtl.
const char* const kBoxObj =
    "# exported by hand\nmtllib box.mtl\n"
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 -1\nv 1 0 -1\n"
    "vn 0 0 1\nvn 0 -1 0\n"
    "o front\nusemtl red\nf 1//1 2//1 3//1 4//1\n"
    "o bottom\nusemtl chrome\nf 1//2 5//2 6//2 2//2\n"
    "o loose\nusemtl red\nf 4//1 3//1 5//1\n";
const char* const kBoxMtl = "newmtl red\nKd 0.8 0.1 0.1\nnewmtl chrome\nKs 0.9 0.9 0.9\nillum 3\nnewmtl unused\n";


// --- choosing the importer ----------------------------------------------------------------

TEST(SceneImportTest, JsonFileImportsAsLoadSceneFileLoadsIt) {
  TempFolder folder;
  folder.Write("tri.obj", kTriangle);
  fs::path path = folder.Write("scene.json", kJsonScene);
  EXPECT_EQ(SerializeScene(ImportScene(path)), SerializeScene(LoadSceneFile(path)));
}

TEST(SceneImportTest, EveryExampleSceneImportsUnchanged) {
  int count = 0;
  for (const auto& entry : fs::directory_iterator("tests/scenes")) {
    if (entry.path().extension() != ".json") continue;
    EXPECT_EQ(SerializeScene(ImportScene(entry.path())), SerializeScene(LoadSceneFile(entry.path())))
        << entry.path();
    ++count;
  }
  EXPECT_GE(count, 3);
}

TEST(SceneImportTest, ExtensionFirstThenContent) {
  EXPECT_EQ(FindImporterForFile("a/scene.JSON", "v 0 0 0")->Type(), "tcfarm-json");
  EXPECT_EQ(FindImporterForFile("model.Obj", "{")->Type(), "obj");
  EXPECT_EQ(FindImporterForFile("scene.txt", "\n  {\"camera\": {}}")->Type(), "tcfarm-json");
  EXPECT_EQ(FindImporterForFile("model", "# Blender\n\nmtllib m.mtl\no Cube\n")->Type(), "obj");
  EXPECT_EQ(FindImporterForFile("model", "# only a comment\n"), nullptr);
  EXPECT_EQ(FindImporterForFile("image.png", "\x89PNG\r\n"), nullptr);
  EXPECT_EQ(FindImporterByType("obj")->Extensions(), std::vector<std::string>{".obj"});
  EXPECT_EQ(FindImporterByType("fbx"), nullptr);
}

TEST(SceneImportTest, SniffedFileWithoutExtension) {
  TempFolder folder;
  fs::path path = folder.Write("upload", kTriangle);
  Scene scene = ImportScene(path);
  ASSERT_EQ(scene.shapes.size(), 1u);
  EXPECT_EQ(scene.shapes[0].mesh.triangles.size(), 1u);
}

TEST(SceneImportTest, UnknownFormatAndType) {
  TempFolder folder;
  fs::path path = folder.Write("notes.txt", "hello\n");
  std::string what = ErrorOf([&] { ImportScene(path); });
  EXPECT_NE(what.find("cannot tell the format of scene file"), std::string::npos) << what;
  EXPECT_NE(what.find("expected a file named .gltf, .glb, .json, .obj"), std::string::npos) << what;
  what = ErrorOf([] { ImportSceneBytes("{}", "fbx"); });
  EXPECT_NE(what.find("unknown scene type \"fbx\"; expected one of \"gltf\", \"tcfarm-json\", \"obj\""), std::string::npos)
      << what;
  what = ErrorOf([] { ImportScene("/nonexistent/scene.json"); });
  EXPECT_EQ(what, "scene: cannot read scene file /nonexistent/scene.json; expected a readable scene file");
}

TEST(SceneImportTest, BytesOfEachType) {
  Scene fromJson = ImportSceneBytes(
      R"({"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]}, "render": {"width": 4, "height": 3}})",
      "tcfarm-json");
  EXPECT_EQ(fromJson.render.width, 4);
  EXPECT_EQ(ImportSceneBytes(kTriangle, "obj").shapes.size(), 1u);
  EXPECT_EQ(ImportSceneBytes(kTriangle, "").shapes.size(), 1u);  // sniffed
  // Network data is self-contained: a JSON mesh file or an OBJ material library is refused.
  std::string what = ErrorOf([] { ImportSceneBytes(kJsonScene, "tcfarm-json"); });
  EXPECT_NE(what.find("must inline their meshes"), std::string::npos) << what;
  what = ErrorOf([] { ImportSceneBytes(kBoxObj, "obj"); });
  EXPECT_NE(what.find("the obj scene line 2: material library \"box.mtl\" cannot be resolved"), std::string::npos)
      << what;
}

// --- an OBJ file as a whole scene ----------------------------------------------------------

TEST(SceneImportTest, ObjSceneHasPartsMaterialsCameraAndLight) {
  TempFolder folder;
  folder.Write("models/box.mtl", kBoxMtl);
  Scene scene = ImportScene(folder.Write("models/box.obj", kBoxObj));

  // "default" first, then the used materials by name, as the JSON parser orders them.
  ASSERT_EQ(scene.materials.size(), 3u);
  EXPECT_EQ(scene.materials[0].name, "default");
  EXPECT_EQ(scene.materials[1].name, "chrome");
  EXPECT_DOUBLE_EQ(scene.materials[1].As<Phong>().reflectivity, 0.9);
  EXPECT_EQ(scene.materials[2].name, "red");

  ASSERT_EQ(scene.shapes.size(), 3u);
  EXPECT_EQ(scene.shapes[0].name, "front");
  EXPECT_EQ(scene.shapes[0].material, 2);
  EXPECT_EQ(scene.shapes[0].mesh.vertices.size(), 4u);  // only the vertices it uses
  EXPECT_EQ(scene.shapes[0].mesh.triangles.size(), 2u);
  ASSERT_EQ(scene.shapes[0].mesh.normals.size(), 4u);
  EXPECT_EQ(scene.shapes[0].mesh.normals[0], (Vec3{0, 0, 1}));
  EXPECT_EQ(scene.shapes[1].name, "bottom");
  EXPECT_EQ(scene.shapes[1].material, 1);
  EXPECT_EQ(scene.shapes[2].material, 2);
  EXPECT_FALSE(scene.AnyShapeMoves());

  // The camera looks at the bounds' centre from far enough to see the bounding sphere.
  Vec3 center{0.5, 0.5, -0.5};
  EXPECT_EQ(scene.camera.lookAt.Evaluate(0), center);
  Vec3 position = scene.camera.position.Evaluate(0);
  double distance = std::sqrt((position.x - center.x) * (position.x - center.x) +
                              (position.y - center.y) * (position.y - center.y) +
                              (position.z - center.z) * (position.z - center.z));
  double radius = std::sqrt(3.0) / 2;
  EXPECT_GE(std::asin(radius / distance) * 180 / kPi * 2, 0.8 * scene.camera.verticalFovDegrees);
  EXPECT_LE(std::asin(radius / distance) * 180 / kPi * 2, scene.camera.verticalFovDegrees);
  EXPECT_GT(position.z, center.z);  // from the front
  ASSERT_EQ(scene.lights.size(), 1u);
  EXPECT_EQ(scene.lights[0].type, Light::Type::kDirectional);
}

TEST(SceneImportTest, ObjSceneTravelsAsJson) {
  TempFolder folder;
  folder.Write("box.mtl", kBoxMtl);
  Scene scene = ImportScene(folder.Write("box.obj", kBoxObj));
  std::string written = SerializeScene(scene);
  Scene reread = ParseScene(written);
  EXPECT_EQ(SerializeScene(reread), written);
  EXPECT_EQ(reread.shapes[1].material, scene.shapes[1].material);
  EXPECT_EQ(reread.shapes[0].mesh.normals, scene.shapes[0].mesh.normals);
}

TEST(SceneImportTest, ObjMaterialNamedDefaultReplacesTheBuiltIn) {
  TempFolder folder;
  folder.Write("m.mtl", "newmtl default\nKd 0.1 0.2 0.3\n");
  Scene scene = ImportScene(folder.Write("m.obj", std::string("mtllib m.mtl\nusemtl default\n") + kTriangle));
  ASSERT_EQ(scene.materials.size(), 1u);
  // tinyobjloader's number parser may be an ulp off strtod for MTL values.
  EXPECT_DOUBLE_EQ(scene.materials[0].As<Phong>().diffuse.z, 0.3);
  EXPECT_DOUBLE_EQ(scene.materials[0].As<Phong>().diffuse.x, 0.1);
  EXPECT_EQ(scene.shapes[0].material, 0);
}

TEST(SceneImportTest, ObjSceneErrorsNameFileAndLine) {
  TempFolder folder;
  folder.Write("outside.mtl", "newmtl red\n");
  fs::create_directories(folder.path() / "scene");
  std::string what = ErrorOf([&] { ImportScene(folder.Write("scene/a.obj", "mtllib ../outside.mtl\n")); });
  EXPECT_EQ(what,
            "scene: a.obj line 1: material library \"../outside.mtl\" resolves outside the scene folder; "
            "expected a relative path that stays inside the scene folder");
  what = ErrorOf([&] { ImportScene(folder.Write("scene/b.obj", "\nmtllib missing.mtl\n")); });
  EXPECT_NE(what.find("b.obj line 2: cannot read material library \"missing.mtl\""), std::string::npos) << what;
  what = ErrorOf([&] { ImportScene(folder.Write("scene/c.obj", "v 0 0 0\nv 1 0 0\nf 1 2 3\n")); });
  EXPECT_NE(what.find("c.obj line 3: vertex reference 3 does not name one of the 2 vertices"), std::string::npos)
      << what;
  what = ErrorOf([&] { ImportScene(folder.Write("scene/d.obj", "v 0 0 0\nv 1 1 1\nv 2 2 2\nf 1 2 3\n")); });
  EXPECT_NE(what.find("d.obj: no face with area"), std::string::npos) << what;
  what = ErrorOf([&] { ImportScene(folder.Write("scene/e.obj", "v 0 0 0\nv 9e29 0 0\nv 0 9e29 0\nf 1 2 3\n")); });
  EXPECT_NE(what.find("too far to frame"), std::string::npos) << what;
}

// --- a JSON scene importing a file and adding to it ----------------------------------------

const char* const kAddOn = R"({"import": {"file": "box.obj"},
  "render": {"width": 8, "height": 6, "frames": {"count": 3}},
  "materials": {"red": {"diffuse": [0, 1, 0]}, "gold": {"diffuse": [0.8, 0.6, 0.1]}},
  "lights": [{"type": "point", "position": [0, 4, 0], "intensity": [5, 5, 5]}],
  "shapes": [{"type": "sphere", "center": [2, 0, 0], "radius": 0.5, "material": "chrome"},
             {"type": "sphere", "center": [-2, 0, 0], "radius": 0.5, "material": "gold"}],
  "background": [0.1, 0.2, 0.3]})";

TEST(SceneImportTest, AJsonSceneAddsToTheFileItImports) {
  TempFolder folder;
  folder.Write("box.obj", kBoxObj);
  folder.Write("box.mtl", kBoxMtl);
  const Scene base = ImportScene(folder.path() / "box.obj", ImportOptions{1, "", "", 8, 6, 0});
  const Scene scene = LoadSceneFile(folder.Write("shot.json", kAddOn));
  EXPECT_EQ(scene.render.width, 8);
  EXPECT_EQ(scene.render.frameCount, 3);
  EXPECT_EQ(scene.background, (Vec3{0.1, 0.2, 0.3}));
  ASSERT_EQ(scene.lights.size(), base.lights.size() + 1);  // the file's own, then the scene's
  ASSERT_EQ(scene.shapes.size(), base.shapes.size() + 2);
  EXPECT_EQ(scene.camera.position.Evaluate(0), base.camera.position.Evaluate(0));  // no "camera": the file's framing
  // "red" replaced where the file's shapes use it; "gold" added; "chrome" the file's.
  const auto material = [&](const std::string& name) {
    for (const Material& m : scene.materials) {
      if (m.name == name) return m;
    }
    ADD_FAILURE() << "no material " << name;
    return Material{};
  };
  EXPECT_EQ(material("red").As<Phong>().diffuse, (Vec3{0, 1, 0}));
  EXPECT_EQ(scene.materials[static_cast<size_t>(scene.shapes[0].material)].name, base.materials[static_cast<size_t>(base.shapes[0].material)].name);
  EXPECT_EQ(scene.materials[static_cast<size_t>(scene.shapes.back().material)].name, "gold");
  // Written out, the scene stands alone: nothing of the import remains to resolve.
  const std::string written = SerializeScene(scene);
  EXPECT_EQ(written.find("import"), std::string::npos);
  EXPECT_EQ(SerializeScene(ParseScene(written)), written);
}

TEST(SceneImportTest, AJsonSceneMayChooseItsOwnCamera) {
  TempFolder folder;
  folder.Write("box.obj", kBoxObj);
  folder.Write("box.mtl", kBoxMtl);
  const Scene scene = LoadSceneFile(folder.Write("shot.json", R"({"import": {"file": "box.obj"},
    "camera": {"position": [0, 9, 0], "look_at": [0, 0, 0], "up": [0, 0, -1]}})"));
  EXPECT_EQ(scene.camera.position.Evaluate(0), (Vec3{0, 9, 0}));
}

TEST(SceneImportTest, BadImportsAreRefusedAtImportFile) {
  TempFolder folder;
  folder.Write("box.obj", kBoxObj);
  folder.Write("box.mtl", kBoxMtl);
  folder.Write("broken.obj", "usemtl nowhere\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  folder.Write("other.json", kJsonScene);
  auto failsAt = [&](const std::string& json, const std::string& pointer, const std::string& mention) {
    try {
      LoadSceneFile(folder.Write("shot.json", json));
    } catch (const SceneError& error) {
      EXPECT_EQ(error.pointer(), pointer) << error.what();
      EXPECT_NE(std::string(error.what()).find(mention), std::string::npos) << error.what();
      return;
    }
    ADD_FAILURE() << json << " was accepted";
  };
  failsAt(R"({"import": {"file": "absent.obj"}})", "/import/file", "absent.obj");
  failsAt(R"({"import": {"file": "../box.obj"}})", "/import/file", "inside");
  failsAt(R"({"import": {"file": "other.json"}})", "/import/file", "do not nest");
  failsAt(R"({"import": {"file": "broken.obj"}})", "/import/file", "nowhere");
  failsAt(R"({"import": {"file": "box.obj", "speed": 2}})", "/import/speed", "unknown field");
  failsAt(R"({"import": {}})", "/import/file", "missing");
  failsAt(R"({"import": {"file": "box.obj"}, "render": {"width": 0}})", "/render/width", "");
  const std::string what = ErrorOf([] { ParseScene(R"({"import": {"file": "box.obj"}})"); });
  EXPECT_NE(what.find("without a folder"), std::string::npos) << what;
}

}  // namespace
}  // namespace tcfarm
