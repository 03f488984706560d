// The scene JSON reader: one document -> Scene, each part read and checked by its own file
// (read_scene.cpp: the document, import and render settings; read_materials.cpp: which
// model a material has, its keys read by the model's format (proto/scene/materials/), and
// textures; read_camera_lights.cpp: the camera and the fields every light has, each kind's own read
// by its format (proto/scene/lights/); read_shapes.cpp: the same for shapes
// (proto/scene/shapes/); read_meshes.cpp: mesh geometry and deformation).
#pragma once

#include <algorithm>
#include <cctype>
#include <iterator>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "proto/scene/scene.h"

#include "proto/scene/import/obj_reader.h"
#include "proto/scene/import/scene_files.h"
#include "proto/scene/import/scene_import.h"
#include "proto/scene/parse/animated_values.h"
#include "proto/scene/parse/json_values.h"

namespace tcfarm::scene_parse {

const char* const kDefaultMaterial = "default";

class SceneReader {
 public:
  SceneReader(std::optional<std::filesystem::path> baseDirectory, Checkpoint checkpoint = {});

  Scene Read(const json& document);

  // --- what the shape kinds read with (proto/scene/shapes/) ---

  // A shape's allowed keys: the kind's own, and those every shape has.
  static std::vector<std::string> ShapeFields(std::vector<std::string> specific);

  // A mesh's own triangles, inline or from an OBJ file: a mesh shape's, or a shared one's.
  TriangleMesh ReadMeshGeometry(const Node& node);

  // A mesh shape placing a shared mesh ("mesh_ref").
  void ReadMeshRef(const Node& node, Shape& shape);

  // Morph targets and/or a skin of a mesh shape (deformation.h).
  void ReadDeformation(const Node& node, Shape& shape) const;

  // Counts triangles against the scene's limit, refusing the scene past it at `node`.
  void ChargeTriangles(size_t count, const Node& node);

  // --- what the light kinds read with (proto/scene/lights/) ---

  // A light's required "position", animated over the scene's frames.
  AnimatedVec3 ReadLightPosition(const Node& light) const;

  // A light's required "direction", animated, and non-zero at every frame.
  AnimatedVec3 ReadLightDirection(const Node& light) const;

  // For the material formats (proto/scene/materials/): a texture object, its image
  // resolved inside the scene's folder; `moreKeys` are those its holder adds (a slot's
  // texture coordinates).
  Texture ReadTexture(const Node& node, const std::vector<std::string>& moreKeys = {});

 private:
  template <typename T>
  static void Append(std::vector<T>& to, std::vector<T> more) {
    to.insert(to.end(), std::make_move_iterator(more.begin()), std::make_move_iterator(more.end()));
  }

  // import ---------------------------------------------------------------------------

  // {"import": {"file": "shot.glb", "animation", "camera", "fps"}}: the file's scene, read
  // by its importer with the render size and samples the document asks for (a glTF
  // camera's aspect follows the size).
  Scene ReadImport(const Node& root);

  ImportOptions ReadImportOptions(const Node& root, const Node& node) const;

  // render ---------------------------------------------------------------------------

  // base: an imported scene's settings, which the document's override field by field
  // (width and height then optional).
  RenderSettings ReadRender(const Node& node, const std::optional<RenderSettings>& base = std::nullopt);

  // materials ------------------------------------------------------------------------

  // base: an imported scene's materials, "default" first; the document's add to them, or
  // replace one of the same name.
  std::vector<Material> ReadMaterials(const Node& root, std::vector<Material> base);

  Material ReadMaterial(const Node& node);

  void ReadTextureFile(const Node& image, Texture& texture);

  // camera ---------------------------------------------------------------------------

  Camera ReadCamera(const Node& node);

  void ReadProjection(const Node& node, Camera& camera) const;

  void CheckCameraBasis(const Camera& camera, const Node& node) const;

  // lights ---------------------------------------------------------------------------

  std::vector<Light> ReadLights(const Node& node);

  // The type, then the kind's own fields (its format's), then those every light has.
  Light ReadLight(const Node& node);

  void CheckDirection(const AnimatedVec3& direction, const Node& node) const;

  // shapes ---------------------------------------------------------------------------

  std::vector<Shape> ReadShapes(const Node& node);

  Shape ReadShape(const Node& node);

  void ReadCommonShapeFields(const Node& node, Shape& shape);

  std::string MaterialChoices() const;

  // --- deforming meshes (deformation.h) ---

  static std::vector<Vec3> ReadVec3List(const Node& node, const std::string& what);

  static std::vector<double> ReadWeightList(const Node& node, size_t count, const std::string& expected);

  static MorphTargets ReadMorph(const Node& node);

  Skin ReadSkin(const Node& node) const;

  // Per vertex, 4 or 8 joint indices and as many weights.
  static void ReadInfluences(const Node& node, Skin& skin);

  static bool HasInlineGeometry(const Node& node);

  // Every shared mesh is read and checked, used or not: a scene holds no invalid geometry.
  // The document's shared meshes, beside an imported scene's (which its shapes may place too).
  void AddSharedMeshes(Scene& scene, const Node& node);

  std::map<std::string, std::shared_ptr<const TriangleMesh>> ReadSharedMeshes(const Node& node);

  std::string SharedMeshChoices() const;

  static void ExpectOnePerVertex(const Node& node, size_t vertexCount, const std::string& what);

  // One value per vertex, each read by `read`: what (e.g. "normal"), as an array says it.
  template <typename Read>
  static std::vector<Vec3> ReadPerVertex(const Node& node, size_t vertexCount, const std::string& what,
                                         const std::string& arrayOf, Read read) {
    if (!node.value.is_array()) FailType(node, "an array of " + arrayOf + ", one per vertex");
    ExpectOnePerVertex(node, vertexCount, what);
    std::vector<Vec3> values;
    values.reserve(node.value.size());
    for (size_t i = 0; i < node.value.size(); ++i) values.push_back(read(node.Element(i)));
    return values;
  }

  static std::vector<Vec3> ReadNormals(const Node& node, size_t vertexCount);

  static std::vector<std::array<double, 4>> ReadTangents(const Node& node, size_t vertexCount);
  static std::vector<std::array<double, 2>> ReadUvs(const Node& node, size_t vertexCount);

  static std::vector<Vec3> ReadVertexColors(const Node& node, size_t vertexCount);

  std::vector<Vec3> ReadVertices(const Node& node);

  std::vector<std::array<uint32_t, 3>> ReadTriangles(const Node& node, size_t vertexCount);

  static uint32_t ReadVertexIndex(const Node& node, size_t vertexCount);

  static void CheckMesh(const TriangleMesh& mesh, const Node& verticesNode, const Node& trianglesNode);

  TriangleMesh LoadMeshFile(const Node& node);

  std::filesystem::path ResolveInsideBase(const Node& node, const std::string& name) const;

  std::optional<std::filesystem::path> baseDirectory_;
  Checkpoint checkpoint_;
  FrameRange range_{0, 0};
  NamedTransforms named_;
  std::map<std::string, int> materialIndex_;
  std::map<std::string, std::shared_ptr<const TriangleMesh>> sharedMeshes_;
  std::set<std::string> unplacedMeshes_;  // shared meshes no shape has placed yet
  size_t triangleCount_ = 0;

};

}  // namespace tcfarm::scene_parse
