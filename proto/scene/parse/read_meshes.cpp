// Reading mesh geometry (inline, from an OBJ file, or shared) and its deformation
// (morph targets and skins).
#include "proto/scene/parse/scene_reader.h"

namespace tcfarm::scene_parse {

void SceneReader::ReadDeformation(const Node& node, Shape& shape) const {
  if (!node.Has("skin") && !node.Has("morph")) return;
  auto deformation = std::make_shared<Deformation>();
  if (node.Has("morph")) {
    deformation->hasMorph = true;
    deformation->morph = ReadMorph(node.Member("morph"));
  }
  if (node.Has("skin")) {
    if (node.Has("motion")) {
      Fail(node.MemberPointer("motion"), "a motion on a skinned mesh",
           "no motion: a skinned mesh is placed by its joints alone");
    }
    deformation->hasSkin = true;
    deformation->skin = ReadSkin(node.Member("skin"));
  }
  for (const DeformationProblem& problem : CheckDeformation(*deformation, shape.Mesh().vertices.size())) {
    Fail(node.pointer + problem.where, problem.problem, problem.expected);
  }
  shape.deformation = std::move(deformation);
}

std::vector<Vec3> SceneReader::ReadVec3List(const Node& node, const std::string& what) {
  if (!node.value.is_array()) FailType(node, "an array of " + what + " [x, y, z]");
  std::vector<Vec3> values;
  values.reserve(node.value.size());
  for (size_t i = 0; i < node.value.size(); ++i) values.push_back(ReadVec3(node.Element(i)));
  return values;
}

std::vector<double> SceneReader::ReadWeightList(const Node& node, size_t count, const std::string& expected) {
  if (!node.value.is_array() || (count != 0 && node.value.size() != count)) FailType(node, expected);
  std::vector<double> values;
  for (size_t i = 0; i < node.value.size(); ++i) values.push_back(ReadNumber(node.Element(i), expected));
  return values;
}

MorphTargets SceneReader::ReadMorph(const Node& node) {
  ExpectObject(node, {"targets", "weights"}, "morph targets {\"targets\": [...], \"weights\": ...}");
  MorphTargets morph;
  Node targets = Required(node, "targets", "an array of morph targets {\"positions\", \"normals\"}");
  if (!targets.value.is_array() || targets.value.empty()) {
    FailType(targets, "a non-empty array of morph targets {\"positions\": [...], \"normals\": [...]}");
  }
  for (size_t t = 0; t < targets.value.size(); ++t) {
    Node target = targets.Element(t);
    ExpectObject(target, {"positions", "normals"}, "a morph target {\"positions\": [...], \"normals\": [...]}");
    morph.positionDeltas.push_back(
        ReadVec3List(Required(target, "positions", "position deltas, one per vertex"), "position deltas"));
    morph.normalDeltas.push_back(target.Has("normals") ? ReadVec3List(target.Member("normals"), "normal deltas")
                                                       : std::vector<Vec3>{});
  }
  const size_t count = morph.positionDeltas.size();
  const std::string expected = "an array of " + std::to_string(count) + " weights (one per target)";
  Node weights = Required(node, "weights", "the targets' weights: [w, ...] or {\"keyframes\": [...]}");
  if (weights.value.is_array()) {
    morph.weights = AnimatedWeights::Constant(ReadWeightList(weights, count, expected));
  } else {
    if (!weights.value.is_object()) FailType(weights, "[w, ...] or {\"keyframes\": [...]}");
    ExpectObject(weights, {"keyframes", "interpolation"}, "weight keyframes {\"keyframes\": [...]}");
    auto read = [&](const Node& value) { return ReadWeightList(value, count, expected); };
    morph.weights = AnimatedWeights::Keyframes(ReadKeys<AnimatedWeights::Keyframe>(weights, "[w, ...]", read, read),
                                               ReadInterpolation(weights));
  }
  return morph;
}

Skin SceneReader::ReadSkin(const Node& node) const {
  ExpectObject(node, {"joints", "inverse_bind_matrices", "vertex_joints", "vertex_weights", "offset"},
               "a skin {\"joints\", \"inverse_bind_matrices\", \"vertex_joints\", \"vertex_weights\"}");
  Skin skin;
  Node joints = Required(node, "joints", "an array of joint transforms");
  if (!joints.value.is_array() || joints.value.empty() || joints.value.size() > kMaxJoints) {
    FailType(joints, "an array of 1 to " + std::to_string(kMaxJoints) + " joint transforms");
  }
  for (size_t j = 0; j < joints.value.size(); ++j) skin.joints.push_back(ReadMotion(joints.Element(j), range_, 0, &named_));
  const std::string matrixExpected = "a 3x4 matrix [m00, m01, m02, m03, m10, ..., m23] (row-major, finite)";
  Node matrices = Required(node, "inverse_bind_matrices", "one inverse bind matrix per joint");
  if (!matrices.value.is_array()) FailType(matrices, "an array of " + matrixExpected);
  for (size_t j = 0; j < matrices.value.size(); ++j) {
    Node matrix = matrices.Element(j);
    ExpectArray(matrix, 12, matrixExpected);
    Affine affine;
    for (int row = 0; row < 3; ++row) {
      for (int column = 0; column < 3; ++column) affine.linear[row][column] = ReadNumber(matrix.Element(4 * row + column), matrixExpected);
      affine.offset[row] = ReadNumber(matrix.Element(4 * row + 3), matrixExpected);
    }
    skin.inverseBind.push_back(affine);
  }
  ReadInfluences(node, skin);
  if (node.Has("offset")) skin.worldOffset = ReadVec3(node.Member("offset"));
  return skin;
}

void SceneReader::ReadInfluences(const Node& node, Skin& skin) {
  Node joints = Required(node, "vertex_joints", "per vertex, an array of 4 or 8 joint indices");
  Node weights = Required(node, "vertex_weights", "per vertex, an array of 4 or 8 weights");
  if (!joints.value.is_array() || joints.value.empty()) FailType(joints, "a non-empty array, one entry per vertex");
  if (!weights.value.is_array()) FailType(weights, "an array, one entry per vertex");
  const Node first = joints.Element(0);
  skin.influencesPerVertex = first.value.is_array() && first.value.size() == 8 ? 8 : 4;
  const size_t k = static_cast<size_t>(skin.influencesPerVertex);
  const std::string jointsExpected = "an array of " + std::to_string(k) + " joint indices (as the first vertex has)";
  const std::string weightsExpected = "an array of " + std::to_string(k) + " weights >= 0";
  for (size_t v = 0; v < joints.value.size(); ++v) {
    Node entry = joints.Element(v);
    ExpectArray(entry, k, jointsExpected);
    for (size_t i = 0; i < k; ++i) {
      skin.vertexJoints.push_back(static_cast<uint32_t>(ReadInteger(entry.Element(i), 0, kMaxJoints - 1)));
    }
  }
  for (size_t v = 0; v < weights.value.size(); ++v) {
    const std::vector<double> values = ReadWeightList(weights.Element(v), k, weightsExpected);
    skin.vertexWeights.insert(skin.vertexWeights.end(), values.begin(), values.end());
  }
}

TriangleMesh SceneReader::ReadMeshGeometry(const Node& node) {
  TriangleMesh mesh;
  if (node.Has("file")) {
    if (HasInlineGeometry(node)) {
      Fail(node.MemberPointer("file"), "both a file and inline geometry",
           "either \"file\" or inline \"vertices\" and \"triangles\"");
    }
    mesh = LoadMeshFile(node.Member("file"));
    CheckMesh(mesh, node.Member("file"), node.Member("file"));
    return mesh;
  }
  const std::string expected = "inline \"vertices\" and \"triangles\", or a \"file\"";
  Node vertices = Required(node, "vertices", expected);
  Node triangles = Required(node, "triangles", expected);
  mesh.vertices = ReadVertices(vertices);
  mesh.triangles = ReadTriangles(triangles, mesh.vertices.size());
  if (node.Has("normals")) mesh.normals = ReadNormals(node.Member("normals"), mesh.vertices.size());
  if (node.Has("uvs")) mesh.uvs = ReadUvs(node.Member("uvs"), mesh.vertices.size());
  if (node.Has("uvs1")) mesh.uvs1 = ReadUvs(node.Member("uvs1"), mesh.vertices.size());
  if (node.Has("tangents")) mesh.tangents = ReadTangents(node.Member("tangents"), mesh.vertices.size());
  if (node.Has("colors")) mesh.colors = ReadVertexColors(node.Member("colors"), mesh.vertices.size());
  CheckMesh(mesh, vertices, triangles);
  return mesh;
}

bool SceneReader::HasInlineGeometry(const Node& node) {
  return node.Has("vertices") || node.Has("triangles") || node.Has("normals") || node.Has("uvs") ||
         node.Has("uvs1") || node.Has("tangents") || node.Has("colors");
}

void SceneReader::AddSharedMeshes(Scene& scene, const Node& node) {
  if (!node.value.is_object()) FailType(node, "an object mapping mesh names to meshes");
  for (const auto& entry : node.value.items()) {
    if (scene.meshes.count(entry.key())) {
      Fail(node.MemberPointer(entry.key()), "the imported file has a mesh named " + Quote(entry.key()),
           "a name of its own");
    }
  }
  std::map<std::string, std::shared_ptr<const TriangleMesh>> imported = std::move(scene.meshes);
  scene.meshes = ReadSharedMeshes(node);
  scene.meshes.insert(imported.begin(), imported.end());
}

std::map<std::string, std::shared_ptr<const TriangleMesh>> SceneReader::ReadSharedMeshes(const Node& node) {
  if (!node.value.is_object()) FailType(node, "an object mapping mesh names to meshes");
  for (const auto& entry : node.value.items()) {
    Node mesh = node.Member(entry.key());
    ExpectObject(mesh, {"vertices", "triangles", "normals", "uvs", "uvs1", "tangents", "colors", "file"}, "a shared mesh");
    sharedMeshes_[entry.key()] = std::make_shared<const TriangleMesh>(ReadMeshGeometry(mesh));
    unplacedMeshes_.insert(entry.key());
  }
  return sharedMeshes_;
}

void SceneReader::ReadMeshRef(const Node& node, Shape& shape) {
  Node ref = node.Member("mesh_ref");
  if (HasInlineGeometry(node) || node.Has("file")) {
    Fail(ref.pointer, "both a shared mesh and geometry of its own",
         "either \"mesh_ref\" or inline \"vertices\" and \"triangles\" or a \"file\"");
  }
  shape.meshRef = ReadString(ref, "the name of a shared mesh");
  auto found = sharedMeshes_.find(shape.meshRef);
  if (found == sharedMeshes_.end()) {
    Fail(ref.pointer, "unknown mesh " + Quote(shape.meshRef), SharedMeshChoices());
  }
  shape.sharedMesh = found->second;
  // The table charged the mesh once; every further placement costs a worker its
  // triangles again (a still one is built in place, as an inline copy).
  if (unplacedMeshes_.erase(shape.meshRef) == 0) ChargeTriangles(shape.sharedMesh->triangles.size(), ref);
}

std::string SceneReader::SharedMeshChoices() const {
  if (sharedMeshes_.empty()) return "the name of a mesh in the scene's \"meshes\" (it has none)";
  std::vector<std::string> names;
  for (const auto& entry : sharedMeshes_) names.push_back(Quote(entry.first));
  return "one of the shared meshes " + JoinNames(names);
}

void SceneReader::ExpectOnePerVertex(const Node& node, size_t vertexCount, const std::string& what) {
  if (node.value.size() != vertexCount) {
    Fail(node.pointer, std::to_string(node.value.size()) + " " + what + "s for " + std::to_string(vertexCount) +
                           " vertices",
         "one " + what + " per vertex, in the order of \"vertices\"");
  }
}

std::vector<Vec3> SceneReader::ReadNormals(const Node& node, size_t vertexCount) {
  return ReadPerVertex(node, vertexCount, "normal", "normals [x, y, z]",
                       [](const Node& element) { return ReadVec3(element); });
}

std::vector<std::array<double, 2>> SceneReader::ReadUvs(const Node& node, size_t vertexCount) {
  if (!node.value.is_array()) FailType(node, "an array of texture coordinates [u, v], one per vertex");
  ExpectOnePerVertex(node, vertexCount, "texture coordinate");
  const std::string expected = "an array of 2 finite numbers [u, v]";
  std::vector<std::array<double, 2>> uvs;
  uvs.reserve(node.value.size());
  for (size_t i = 0; i < node.value.size(); ++i) {
    Node uv = node.Element(i);
    ExpectArray(uv, 2, expected);
    uvs.push_back({ReadNumber(uv.Element(0), expected), ReadNumber(uv.Element(1), expected)});
  }
  return uvs;
}

std::vector<std::array<double, 4>> SceneReader::ReadTangents(const Node& node, size_t vertexCount) {
  if (!node.value.is_array()) FailType(node, "an array of tangents [x, y, z, w], one per vertex");
  ExpectOnePerVertex(node, vertexCount, "tangent");
  const std::string expected = "a tangent [x, y, z, w] of finite numbers, w = 1 or -1";
  std::vector<std::array<double, 4>> tangents;
  tangents.reserve(node.value.size());
  for (size_t i = 0; i < node.value.size(); ++i) {
    Node tangent = node.Element(i);
    ExpectArray(tangent, 4, expected);
    std::array<double, 4> t{};
    for (size_t c = 0; c < 4; ++c) t[c] = ReadNumber(tangent.Element(c), expected);
    if (t[3] != 1 && t[3] != -1) Fail(tangent.pointer + "/3", "a handedness of " + FormatNumber(t[3]), expected);
    tangents.push_back(t);
  }
  return tangents;
}

std::vector<Vec3> SceneReader::ReadVertexColors(const Node& node, size_t vertexCount) {
  return ReadPerVertex(node, vertexCount, "colour", "linear RGB colours [r, g, b]", ReadColour);
}

std::vector<Vec3> SceneReader::ReadVertices(const Node& node) {
  if (!node.value.is_array()) FailType(node, "an array of vertices [x, y, z]");
  std::vector<Vec3> vertices;
  vertices.reserve(node.value.size());
  for (size_t i = 0; i < node.value.size(); ++i) vertices.push_back(ReadVec3(node.Element(i)));
  return vertices;
}

std::vector<std::array<uint32_t, 3>> SceneReader::ReadTriangles(const Node& node, size_t vertexCount) {
  if (!node.value.is_array()) FailType(node, "an array of triangles [i, j, k]");
  ChargeTriangles(node.value.size(), node);
  std::vector<std::array<uint32_t, 3>> triangles;
  triangles.reserve(node.value.size());
  const std::string expected = "a triangle [i, j, k] of vertex indices";
  for (size_t t = 0; t < node.value.size(); ++t) {
    Node triangle = node.Element(t);
    ExpectArray(triangle, 3, expected);
    std::array<uint32_t, 3> corners{};
    for (size_t c = 0; c < 3; ++c) corners[c] = ReadVertexIndex(triangle.Element(c), vertexCount);
    triangles.push_back(corners);
  }
  return triangles;
}

uint32_t SceneReader::ReadVertexIndex(const Node& node, size_t vertexCount) {
  std::string expected = "an integer in [0, " + std::to_string(vertexCount) + "), the index of one of the mesh's " +
                         std::to_string(vertexCount) + " vertices";
  if (!IsIntegral(node.value)) FailType(node, expected);
  double index = node.value.get<double>();
  if (index < 0 || index >= static_cast<double>(vertexCount)) {
    Fail(node.pointer, "index " + Show(node.value) + " is out of range", expected);
  }
  return static_cast<uint32_t>(index);
}

void SceneReader::CheckMesh(const TriangleMesh& mesh, const Node& verticesNode, const Node& trianglesNode) {
  if (mesh.vertices.empty()) {
    Fail(verticesNode.pointer, "the mesh has no vertices", "a mesh with at least 3 vertices");
  }
  if (mesh.triangles.empty()) Fail(trianglesNode.pointer, "the mesh has no triangles", "at least one triangle");
  for (const auto& t : mesh.triangles) {
    const Vec3& a = mesh.vertices[t[0]];
    if (!IsDegenerate(Subtract(mesh.vertices[t[1]], a), Subtract(mesh.vertices[t[2]], a))) return;
  }
  Fail(trianglesNode.pointer, "every triangle of the mesh has zero area", "at least one triangle with area");
}

void SceneReader::ChargeTriangles(size_t count, const Node& node) {
  if (count > kMaxTriangles - triangleCount_) {
    Fail(node.pointer, "the scene would have " + std::to_string(triangleCount_ + count) + " triangles",
         "at most 20000000 triangles in the whole scene");
  }
  triangleCount_ += count;
}

TriangleMesh SceneReader::LoadMeshFile(const Node& node) {
  std::string name = ReadString(node, "a path to an OBJ file inside the scene folder");
  if (!baseDirectory_) {
    Fail(node.pointer, "mesh file " + Quote(name) + " cannot be resolved: the scene was submitted without a folder",
         "inline \"vertices\" and \"triangles\" (scenes submitted without a folder must inline their meshes)");
  }
  std::string text = ReadSceneFile(ResolveInsideBase(node, name), name, node.pointer, "mesh file",
                                   "a readable OBJ file inside the scene folder");
  // Geometry only: the JSON shape names the material, so the file's mtllib/usemtl are
  // not read (a whole OBJ imported as a scene keeps them).
  ObjReadOptions options;
  options.pointer = node.pointer;
  options.displayName = name;
  options.triangleBudget = kMaxTriangles - triangleCount_;
  options.triangleLimit = kMaxTriangles;
  TriangleMesh mesh = ReadObj(text, options).mesh;
  triangleCount_ += mesh.triangles.size();
  return mesh;
}

std::filesystem::path SceneReader::ResolveInsideBase(const Node& node, const std::string& name) const {
  return ResolveInsideFolder(*baseDirectory_, name, node.pointer, "mesh file");
}

}  // namespace tcfarm::scene_parse
