// A whole Wavefront OBJ file (with its MTL libraries) as a scene: one mesh shape per run of
// faces of one object/group and material, the materials its faces use, and what OBJ does
// not describe: a camera framing the model's bounds, one light, default render settings.
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "proto/scene/import/mesh_geometry.h"
#include "proto/scene/import/importers.h"
#include "proto/scene/import/messages.h"
#include "proto/scene/import/obj_reader.h"
#include "proto/scene/import/scene_files.h"
#include "proto/scene/scene_limits.h"

namespace tcfarm {
namespace {

using import::BoundingBox;
using import::CrossProduct;
using import::FramingPose;
using import::kFramingFovDegrees;
using import::HasArea;
using import::Norm;
using import::Sub;

using scene_limits::kMaxMagnitude;


// One part's triangles with only the vertices they use, in order of first use.
TriangleMesh PartMesh(const TriangleMesh& all, const ObjModel::Part& part) {
  TriangleMesh mesh;
  std::map<uint32_t, uint32_t> renumbered;
  auto vertex = [&](uint32_t index) {
    auto [found, inserted] = renumbered.try_emplace(index, static_cast<uint32_t>(mesh.vertices.size()));
    if (inserted) {
      mesh.vertices.push_back(all.vertices[index]);
      if (!all.normals.empty()) mesh.normals.push_back(all.normals[index]);
      if (!all.uvs.empty()) mesh.uvs.push_back(all.uvs[index]);
    }
    return found->second;
  };
  for (size_t t = part.firstTriangle; t < part.firstTriangle + part.triangleCount; ++t) {
    const auto& triangle = all.triangles[t];
    mesh.triangles.push_back({vertex(triangle[0]), vertex(triangle[1]), vertex(triangle[2])});
  }
  return mesh;
}

// Materials as the scene parser orders them ("default" first, then by name), so that the
// scene serialises and reads back with the same indices. Returns, per OBJ material, its
// index in the scene (0, the default, for those no face uses).
std::vector<int> AddMaterials(const ObjModel& model, Scene& scene) {
  std::vector<bool> used(model.materials.size(), false);
  for (const auto& part : model.parts) {
    if (part.material >= 0) used[static_cast<size_t>(part.material)] = true;
  }
  std::map<std::string, size_t> byName;  // sorted, as the parser's materials object
  for (size_t i = 0; i < model.materials.size(); ++i) {
    if (used[i]) byName.emplace(model.materials[i].name, i);
  }
  scene.materials.assign(1, Material{});
  scene.materials[0].name = "default";
  std::vector<int> sceneIndex(model.materials.size(), 0);
  for (const auto& [name, objIndex] : byName) {
    // An MTL material called "default" replaces the built-in one, as in scene JSON.
    if (name == "default") {
      scene.materials[0] = model.materials[objIndex];
      continue;
    }
    sceneIndex[objIndex] = static_cast<int>(scene.materials.size());
    scene.materials.push_back(model.materials[objIndex]);
  }
  return sceneIndex;
}

void FrameBounds(const std::vector<Shape>& shapes, Scene& scene, const std::string& displayName) {
  BoundingBox box;
  for (const Shape& shape : shapes) box.Add(shape.mesh.vertices);
  const CameraPose pose = FramingPose(box, displayName);
  scene.camera.position = AnimatedVec3::Constant(pose.position);
  scene.camera.lookAt = AnimatedVec3::Constant(pose.lookAt);
  scene.camera.verticalFovDegrees = kFramingFovDegrees;
}

class ObjImporter : public SceneImporter {
 public:
  std::string Type() const override { return "obj"; }
  std::vector<std::string> Extensions() const override { return {".obj"}; }

  // The first statement (after comments and blank lines) is one OBJ files start with.
  bool Sniff(std::string_view head) const override {
    static const char* const kStatements[] = {"v", "vn", "vt", "f", "o", "g", "s", "mtllib", "usemtl"};
    size_t begin = 0;
    while (begin < head.size()) {
      size_t end = std::min(head.find('\n', begin), head.size());
      std::string_view line = head.substr(begin, end - begin);
      size_t first = line.find_first_not_of(" \t\r");
      if (first != std::string_view::npos && line[first] != '#') {
        std::string_view keyword = line.substr(first, line.find_first_of(" \t", first) - first);
        return std::find(std::begin(kStatements), std::end(kStatements), keyword) != std::end(kStatements);
      }
      begin = end + 1;
    }
    return false;
  }

  Scene Import(const ImportInput& input) const override {
    ObjReadOptions options;
    options.pointer = "";
    options.displayName = input.displayName;
    options.triangleBudget = scene_limits::kMaxTriangles;
    options.triangleLimit = scene_limits::kMaxTriangles;
    options.readMaterialLibrary = [&input](const std::string& name, size_t line) {
      std::string where = input.displayName + " line " + std::to_string(line) + ": ";
      if (!input.baseDirectory) {
        FailInput("", where + "material library " + QuoteInput(name) +
                          " cannot be resolved: the OBJ was submitted without a folder",
                  "an OBJ without mtllib, or one imported from a folder holding its libraries");
      }
      try {
        std::filesystem::path path = ResolveInsideFolder(*input.baseDirectory, name, "", "material library");
        return ReadSceneFile(path, name, "", "material library", "a readable MTL file inside the scene folder");
      } catch (const SceneError& error) {
        // Name the OBJ line that asked for the library.
        throw SceneError("", where + std::string(error.what()).substr(std::string("scene: ").size()));
      }
    };
    ObjModel model = ReadObj(input.bytes, options);

    Scene scene;
    std::vector<int> materialIndex = AddMaterials(model, scene);
    for (const auto& part : model.parts) {
      Shape shape;
      shape.type = Shape::Type::kMesh;
      shape.name = part.name;
      shape.material = part.material >= 0 ? materialIndex[static_cast<size_t>(part.material)] : 0;
      shape.mesh = PartMesh(model.mesh, part);
      // Faces without area draw nothing, and the parser refuses a mesh made only of them.
      if (HasArea(shape.mesh)) scene.shapes.push_back(std::move(shape));
    }
    if (scene.shapes.empty()) {
      FailInput("", input.displayName + ": no face with area", "an OBJ with at least one face of non-zero area");
    }
    FrameBounds(scene.shapes, scene, input.displayName);
    Light light;
    light.type = Light::Type::kDirectional;
    light.direction = AnimatedVec3::Constant(import::kDefaultLightDirection);
    light.intensity = AnimatedVec3::Constant(Vec3{1, 1, 1});
    scene.lights.push_back(light);
    return scene;
  }
};

}  // namespace

std::unique_ptr<SceneImporter> MakeObjImporter() { return std::make_unique<ObjImporter>(); }

}  // namespace tcfarm
