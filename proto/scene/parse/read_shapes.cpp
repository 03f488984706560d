// Reading a scene's shapes: spheres, quads, meshes and terrain.
#include "proto/scene/parse/scene_reader.h"

namespace tcfarm::scene_parse {

std::vector<Shape> SceneReader::ReadShapes(const Node& node) {
  if (!node.value.is_array()) FailType(node, "an array of shapes");
  std::vector<Shape> shapes;
  for (size_t i = 0; i < node.value.size(); ++i) shapes.push_back(ReadShape(node.Element(i)));
  return shapes;
}

Shape SceneReader::ReadShape(const Node& node) {
  const std::string typeExpected = "\"sphere\", \"quad\", \"mesh\" or \"terrain\"";
  if (!node.value.is_object()) FailType(node, "a shape {\"type\": " + typeExpected + ", ...}");
  std::string type = ReadString(Required(node, "type", typeExpected), typeExpected);
  Shape shape;
  if (type == "sphere") {
    ReadSphere(node, shape);
  } else if (type == "quad") {
    ReadQuad(node, shape);
  } else if (type == "mesh") {
    ReadMesh(node, shape);
  } else if (type == "terrain") {
    ReadTerrain(node, shape);
  } else {
    Fail(node.MemberPointer("type"), "unknown shape type " + Quote(type), typeExpected);
  }
  ReadCommonShapeFields(node, shape);
  return shape;
}

std::vector<std::string> SceneReader::ShapeFields(std::vector<std::string> specific) {
  specific.insert(specific.begin(), {"type", "name", "material", "motion"});
  return specific;
}

void SceneReader::ReadCommonShapeFields(const Node& node, Shape& shape) {
  if (node.Has("name")) shape.name = ReadString(node.Member("name"), "a string");
  if (node.Has("motion")) shape.motion = ReadMotion(node.Member("motion"), range_, 0, &named_);
  if (node.Has("material")) {
    Node material = node.Member("material");
    std::string name = ReadString(material, "the name of a material");
    auto found = materialIndex_.find(name);
    if (found == materialIndex_.end()) Fail(material.pointer, "unknown material " + Quote(name), MaterialChoices());
    shape.material = found->second;
  }
}

std::string SceneReader::MaterialChoices() const {
  std::vector<std::string> names;
  for (const auto& entry : materialIndex_) names.push_back(Quote(entry.first));
  return "one of the materials " + JoinNames(names);
}

void SceneReader::ReadSphere(const Node& node, Shape& shape) {
  ExpectObject(node, ShapeFields({"center", "radius"}), "a sphere");
  shape.type = Shape::Type::kSphere;
  shape.center = ReadVec3(Required(node, "center", kVec3Expected));
  shape.radius = ReadPositive(Required(node, "radius", "a positive finite number"), "a positive finite number");
}

void SceneReader::ReadQuad(const Node& node, Shape& shape) {
  ExpectObject(node, ShapeFields({"corner", "edge_u", "edge_v"}), "a quad");
  shape.type = Shape::Type::kQuad;
  shape.corner = ReadVec3(Required(node, "corner", kVec3Expected));
  shape.edgeU = ReadVec3(Required(node, "edge_u", kVec3Expected));
  shape.edgeV = ReadVec3(Required(node, "edge_v", kVec3Expected));
  if (IsDegenerate(shape.edgeU, shape.edgeV)) {
    Fail(node.pointer, "edge_u x edge_v is zero: the quad has no area",
         "edge_u and edge_v non-zero and not parallel");
  }
}

void SceneReader::ReadMesh(const Node& node, Shape& shape) {
  ExpectObject(node, ShapeFields({"vertices", "triangles", "normals", "uvs", "uvs1", "tangents", "colors", "file", "mesh_ref", "skin", "morph"}),
               "a mesh");
  shape.type = Shape::Type::kMesh;
  if (node.Has("mesh_ref")) {
    ReadMeshRef(node, shape);
  } else {
    shape.mesh = ReadMeshGeometry(node);
  }
  ReadDeformation(node, shape);
}

void SceneReader::ReadTerrain(const Node& node, Shape& shape) {
  ExpectObject(node, ShapeFields({"origin", "size", "height", "cells", "seed"}), "a terrain");
  shape.type = Shape::Type::kTerrain;
  Shape::Terrain& terrain = shape.terrain;
  terrain.origin = ReadVec3(Required(node, "origin", kVec3Expected));
  const std::string sizeExpected = "[size_x, size_z], two positive finite numbers";
  Node size = Required(node, "size", sizeExpected);
  ExpectArray(size, 2, sizeExpected);
  terrain.sizeX = ReadPositive(size.Element(0), sizeExpected);
  terrain.sizeZ = ReadPositive(size.Element(1), sizeExpected);
  if (node.Has("height")) terrain.height = ReadNonNegative(node.Member("height"), "a non-negative finite height");
  if (node.Has("cells")) ReadTerrainCells(node.Member("cells"), terrain);
  if (node.Has("seed")) terrain.seed = ReadSeed(node.Member("seed"));
  ChargeTriangles(2 * static_cast<size_t>(terrain.cellsX) * static_cast<size_t>(terrain.cellsZ),
                  node.Has("cells") ? node.Member("cells") : node);
}

void SceneReader::ReadTerrainCells(const Node& node, Shape::Terrain& terrain) {
  ExpectArray(node, 2, "[cells_x, cells_z], two integers in [1, 2000]");
  terrain.cellsX = ReadInt(node.Element(0), 1, kMaxTerrainCells);
  terrain.cellsZ = ReadInt(node.Element(1), 1, kMaxTerrainCells);
}

uint64_t SceneReader::ReadSeed(const Node& node) {
  const std::string expected = "an integer in [0, 18446744073709551615]";
  if (node.value.is_number_unsigned()) return node.value.get<uint64_t>();
  if (node.value.is_number_integer()) Fail(node.pointer, Show(node.value) + " is negative", expected);
  FailType(node, expected);
}

}  // namespace tcfarm::scene_parse
