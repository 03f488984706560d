// Mesh primitives as shapes: positions, normals, texture coordinates, colours, triangles.
#include "proto/scene/import/gltf/gltf_reader.h"

namespace tcfarm::gltf {

TriangleMesh GltfReader::PrimitiveMesh(const tinygltf::Primitive& primitive, const std::string& pointer) const {
  auto position = primitive.attributes.find("POSITION");
  if (position == primitive.attributes.end()) {
    Fail(pointer + "/attributes", "no POSITION attribute", "a primitive with POSITION");
  }
  const std::vector<int> anyComponent = {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE,
                                         TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_SHORT,
                                         TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT};
  AccessorData positions = ReadAccessor(position->second, pointer + "/attributes/POSITION", {TINYGLTF_TYPE_VEC3},
                                        anyComponent, "a VEC3 accessor of positions");
  CheckFinite(positions, position->second, "position");
  TriangleMesh mesh;
  // Reserved, not grown: a vector grown by doubling may hold twice the vertices, and both
  // copies while it moves, beyond what the import budget was charged (ChargeValues).
  mesh.vertices.reserve(positions.count);
  for (size_t v = 0; v < positions.count; ++v)
    mesh.vertices.push_back({positions.At(v, 0), positions.At(v, 1), positions.At(v, 2)});
  if (auto normal = primitive.attributes.find("NORMAL"); normal != primitive.attributes.end()) {
    AccessorData normals =
        ReadAccessor(normal->second, pointer + "/attributes/NORMAL", {TINYGLTF_TYPE_VEC3},
                     {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE, TINYGLTF_COMPONENT_TYPE_SHORT},
                     "a VEC3 accessor of normals");
    CheckFinite(normals, normal->second, "normal");
    CheckNormalized(normal->second, "normals");
    if (normals.count != positions.count) {
      Fail(Pointer("accessors", static_cast<size_t>(normal->second)) + "/count",
           std::to_string(normals.count) + " normals for " + std::to_string(positions.count) + " positions",
           "one normal per position");
    }
    mesh.normals.reserve(normals.count);
    for (size_t v = 0; v < normals.count; ++v)
      mesh.normals.push_back({normals.At(v, 0), normals.At(v, 1), normals.At(v, 2)});
  }
  mesh.uvs = ReadTexCoords(primitive, "TEXCOORD_0", pointer, positions.count);
  mesh.uvs1 = ReadTexCoords(primitive, "TEXCOORD_1", pointer, positions.count);
  if (auto tangent = primitive.attributes.find("TANGENT"); tangent != primitive.attributes.end()) {
    mesh.tangents = ReadTangents(tangent->second, pointer + "/attributes/TANGENT", positions.count);
  }
  if (auto color = primitive.attributes.find("COLOR_0"); color != primitive.attributes.end()) {
    mesh.colors = ReadVertexColors(color->second, pointer + "/attributes/COLOR_0", positions.count);
  }
  std::vector<uint32_t> indices;
  if (primitive.indices >= 0) {
    AccessorData data = ReadAccessor(primitive.indices, pointer + "/indices", {TINYGLTF_TYPE_SCALAR},
                                     {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                                      TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT},
                                     "a SCALAR accessor of unsigned indices");
    indices.reserve(data.count);
    for (size_t i = 0; i < data.count; ++i) {
      double index = data.values[i];
      if (!(index < static_cast<double>(positions.count))) {
        Fail(Pointer("accessors", static_cast<size_t>(primitive.indices)),
             "index " + std::to_string(i) + " is " + std::to_string(static_cast<uint64_t>(index)) +
                 ", out of range for " + std::to_string(positions.count) + " vertices",
             "indices below the vertex count");
      }
      indices.push_back(static_cast<uint32_t>(index));
    }
  } else {
    indices.reserve(positions.count);
    for (size_t v = 0; v < positions.count; ++v) indices.push_back(static_cast<uint32_t>(v));
  }
  int mode = primitive.mode < 0 ? TINYGLTF_MODE_TRIANGLES : primitive.mode;
  if (const size_t leftOver = indices.size() % 3; mode == TINYGLTF_MODE_TRIANGLES && leftOver != 0) {
    Warn("incomplete_triangle", pointer,
         std::to_string(indices.size()) + (primitive.indices >= 0 ? " indices" : " vertices") +
             " are not whole triangles; the last " + (leftOver == 1 ? "one is" : "two are") + " left out");
  }
  mesh.triangles = Triangles(indices, mode);
  return mesh;
}

std::vector<std::array<uint32_t, 3>> GltfReader::Triangles(const std::vector<uint32_t>& indices, int mode) {
  std::vector<std::array<uint32_t, 3>> triangles;
  const size_t n = indices.size();
  triangles.reserve(mode == TINYGLTF_MODE_TRIANGLES ? n / 3 : n);
  if (mode == TINYGLTF_MODE_TRIANGLES) {
    for (size_t i = 0; i + 2 < n; i += 3) triangles.push_back({indices[i], indices[i + 1], indices[i + 2]});
  } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
    for (size_t i = 0; i + 2 < n; ++i) {
      triangles.push_back({indices[i], indices[i + 1 + i % 2], indices[i + 2 - i % 2]});
    }
  } else if (mode == TINYGLTF_MODE_TRIANGLE_FAN) {
    for (size_t i = 0; i + 2 < n; ++i) triangles.push_back({indices[i + 1], indices[i + 2], indices[0]});
  }
  return triangles;
}

std::vector<int> GltfReader::NodesPerMesh() const {
  std::vector<int> count(model_.meshes.size(), 0);
  for (int node : order_) {
    const int mesh = model_.nodes[static_cast<size_t>(node)].mesh;
    if (mesh >= 0 && static_cast<size_t>(mesh) < count.size()) ++count[static_cast<size_t>(mesh)];
  }
  return count;
}

std::string GltfReader::SharedMeshName(const tinygltf::Mesh& mesh, size_t meshIndex, size_t primitive,
                                  const Scene& scene) {
  std::string name = mesh.name.empty() ? "mesh" + std::to_string(meshIndex) : mesh.name;
  if (mesh.primitives.size() > 1) name += "/" + std::to_string(primitive);
  if (scene.meshes.count(name)) name += "#" + std::to_string(meshIndex);
  return name;
}

void GltfReader::SetPrimitiveMesh(Shape& shape, size_t meshIndex, size_t p, bool shared, const std::string& pointer,
                      Scene& scene) {
  if (!shared) {
    shape.mesh = PrimitiveMesh(model_.meshes[meshIndex].primitives[p], pointer);
    return;
  }
  auto [entry, isNew] = sharedPrimitives_.try_emplace({meshIndex, p});
  if (isNew) {
    auto mesh = std::make_shared<const TriangleMesh>(PrimitiveMesh(model_.meshes[meshIndex].primitives[p], pointer));
    // A primitive without area is skipped at every node: it never enters the table.
    entry->second.name = HasArea(*mesh) ? SharedMeshName(model_.meshes[meshIndex], meshIndex, p, scene) : "";
    if (!entry->second.name.empty()) scene.meshes[entry->second.name] = mesh;
    entry->second.mesh = std::move(mesh);
  }
  shape.sharedMesh = entry->second.mesh;
  shape.meshRef = entry->second.name;
}

void GltfReader::AddShapes(Scene& scene) {
  size_t triangles = 0;
  const std::vector<int> nodesPerMesh = NodesPerMesh();
  for (int node : order_) {
    const auto& source = model_.nodes[static_cast<size_t>(node)];
    if (source.mesh < 0) continue;
    const std::string nodePointer = Pointer("nodes", static_cast<size_t>(node));
    if (static_cast<size_t>(source.mesh) >= model_.meshes.size()) {
      Fail(nodePointer + "/mesh", "mesh " + std::to_string(source.mesh) + " does not exist", "the index of a mesh");
    }
    // A skinned mesh is placed by its joints alone: glTF ignores its node's transform.
    const SkinJoints* skin = source.skin >= 0 ? &ReadSkin(static_cast<size_t>(node)) : nullptr;
    MorphTargetCount(static_cast<size_t>(node));  // refuses primitives with different target counts
    const auto& mesh = model_.meshes[static_cast<size_t>(source.mesh)];
    for (size_t p = 0; p < mesh.primitives.size(); ++p) {
      const auto& primitive = mesh.primitives[p];
      const std::string pointer =
          Pointer("meshes", static_cast<size_t>(source.mesh)) + "/primitives/" + std::to_string(p);
      int mode = primitive.mode < 0 ? TINYGLTF_MODE_TRIANGLES : primitive.mode;
      if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
          mode != TINYGLTF_MODE_TRIANGLE_FAN) {
        if (mode < TINYGLTF_MODE_POINTS || mode > TINYGLTF_MODE_TRIANGLE_FAN) {
          Fail(pointer + "/mode", "mode " + std::to_string(mode), "a primitive mode from 0 to 6");
        }
        Warn("primitive_mode_skipped", pointer, "points and lines are not rendered; the primitive is skipped");
        continue;
      }
      Shape shape;
      shape.type = Shape::Type::kMesh;
      shape.name = (source.name.empty() ? "node" + std::to_string(node) : source.name) +
                   (mesh.primitives.size() > 1 ? "/" + std::to_string(p) : "");
      if (primitive.material >= 0) {
        if (static_cast<size_t>(primitive.material) >= model_.materials.size()) {
          Fail(pointer + "/material", "material " + std::to_string(primitive.material) + " does not exist",
               "the index of a material");
        }
        shape.material = materialIndex_[static_cast<size_t>(primitive.material)];
      }
      SetPrimitiveMesh(shape, static_cast<size_t>(source.mesh), p, nodesPerMesh[static_cast<size_t>(source.mesh)] > 1,
                       pointer, scene);
      if (!HasArea(shape.Mesh())) {
        Warn("primitive_without_area", pointer, "no triangle with area; the primitive is skipped");
        continue;
      }
      WarnOfMissingTexCoords(scene.materials[static_cast<size_t>(shape.material)], shape.Mesh(), pointer);
      triangles += shape.Mesh().triangles.size();
      if (triangles > kMaxTriangles) {
        Fail(pointer, "more than " + std::to_string(kMaxTriangles) + " triangles in all", "a smaller scene");
      }
      shape.deformation =
          PrimitiveDeformation(static_cast<size_t>(node), skin, primitive, pointer, shape.Mesh());
      if (skin == nullptr) shape.motion = *motions_[static_cast<size_t>(node)];
      scene.shapes.push_back(std::move(shape));
    }
  }
  // A valid file may draw nothing (an empty scene, points or lines only): its frames show
  // only the background, which would look like a failed render unless said.
  if (scene.shapes.empty()) {
    const size_t chosen = model_.defaultScene >= 0 ? static_cast<size_t>(model_.defaultScene) : 0;
    Warn("empty_scene", model_.scenes.empty() ? "/nodes" : Pointer("scenes", chosen),
         "no node of the scene draws a triangle; the frames show only the background");
  }
}

void GltfReader::WarnOfMissingTexCoords(const Material& material, const TriangleMesh& mesh,
                                        const std::string& pointer) const {
  for (int set : {0, 1}) {
    const bool present = !(set == 0 ? mesh.uvs : mesh.uvs1).empty();
    if (material.ReadsTexCoord(set) && !present) {
      Warn("texcoord_set_missing", pointer + "/attributes",
           "the material's textures read TEXCOORD_" + std::to_string(set) +
               ", which this primitive does not have; those textures are left out and their factors used");
    }
  }
}

std::vector<Vec3> GltfReader::ReadVertexColors(int index, const std::string& referencedAt, size_t positions) const {
  AccessorData colors = ReadAccessor(
      index, referencedAt, {TINYGLTF_TYPE_VEC3, TINYGLTF_TYPE_VEC4},
      {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT},
      "a VEC3 or VEC4 accessor of colours (FLOAT, or normalized UNSIGNED_BYTE or UNSIGNED_SHORT)");
  const std::string pointer = Pointer("accessors", static_cast<size_t>(index));
  const tinygltf::Accessor& accessor = model_.accessors[static_cast<size_t>(index)];
  if (accessor.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT && !accessor.normalized) {
    Fail(pointer + "/normalized", "integer colours that are not normalized", "normalized: true on integer colours");
  }
  CheckFinite(colors, index, "colour");
  if (colors.count != positions) {
    Fail(pointer + "/count", std::to_string(colors.count) + " colours for " + std::to_string(positions) + " positions",
         "one colour per position");
  }
  std::vector<Vec3> result;
  result.reserve(colors.count);
  for (size_t v = 0; v < colors.count; ++v) {
    Vec3 rgb{colors.At(v, 0), colors.At(v, 1), colors.At(v, 2)};
    for (int c = 0; c < 3; ++c) {
      if (!(rgb[c] >= 0)) {
        Fail(pointer, "colour " + std::to_string(v) + " has a negative component " + std::to_string(rgb[c]),
             "colours in [0, 1]");
      }
    }
    result.push_back(rgb);
  }
  return result;
}

}  // namespace tcfarm::gltf

namespace tcfarm::gltf {

std::vector<std::array<double, 2>> GltfReader::ReadTexCoords(const tinygltf::Primitive& primitive,
                                                             const std::string& attribute, const std::string& pointer,
                                                             size_t positions) const {
  auto uv = primitive.attributes.find(attribute);
  if (uv == primitive.attributes.end()) return {};
  AccessorData uvs = ReadAccessor(uv->second, pointer + "/attributes/" + attribute, {TINYGLTF_TYPE_VEC2},
                                  {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE,
                                   TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_SHORT,
                                   TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT},
                                  "a VEC2 accessor of texture coordinates");
  CheckFinite(uvs, uv->second, "texture coordinate");
  if (uvs.count != positions) {
    Fail(Pointer("accessors", static_cast<size_t>(uv->second)) + "/count",
         std::to_string(uvs.count) + " texture coordinates for " + std::to_string(positions) + " positions",
         "one per position");
  }
  std::vector<std::array<double, 2>> result;
  result.reserve(uvs.count);
  for (size_t v = 0; v < uvs.count; ++v) result.push_back({uvs.At(v, 0), uvs.At(v, 1)});
  return result;
}

std::vector<std::array<double, 4>> GltfReader::ReadTangents(int index, const std::string& pointer,
                                                            size_t positions) const {
  AccessorData tangents =
      ReadAccessor(index, pointer, {TINYGLTF_TYPE_VEC4},
                   {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE, TINYGLTF_COMPONENT_TYPE_SHORT},
                   "a VEC4 accessor of tangents");
  CheckFinite(tangents, index, "tangent");
  if (tangents.count != positions) {
    Fail(Pointer("accessors", static_cast<size_t>(index)) + "/count",
         std::to_string(tangents.count) + " tangents for " + std::to_string(positions) + " positions",
         "one tangent per position");
  }
  std::vector<std::array<double, 4>> result;
  result.reserve(tangents.count);
  for (size_t v = 0; v < tangents.count; ++v) {
    // w is the bitangent's sign, +-1 by the specification; a quantized file may hold it
    // rounded, so only its sign is kept.
    result.push_back({tangents.At(v, 0), tangents.At(v, 1), tangents.At(v, 2), tangents.At(v, 3) < 0 ? -1.0 : 1.0});
  }
  return result;
}

}  // namespace tcfarm::gltf
