// A triangle mesh: {"type": "mesh"} with its own triangles (inline, or an OBJ "file"), or
// placing a shared one ("mesh_ref"), perhaps deformed by morph targets and a skin. The
// geometry itself is read by SceneReader (read_meshes.cpp), which shared meshes read too.
#include "proto/scene/parse/scene_reader.h"
#include "proto/scene/scene_write.h"
#include "proto/scene/shapes/shape_format.h"

namespace tcfarm {
namespace {

using namespace scene_parse;

class MeshFormatImpl final : public ShapeFormat {
 public:
  const char* Name() const override { return "mesh"; }

  void Read(SceneReader& reader, const Node& node, Shape& shape) const override {
    ExpectObject(node,
                 SceneReader::ShapeFields({"vertices", "triangles", "normals", "uvs", "uvs1", "tangents", "colors", "file", "mesh_ref",
                                           "skin", "morph"}),
                 "a mesh");
    if (node.Has("mesh_ref")) {
      reader.ReadMeshRef(node, shape);
    } else {
      shape.mesh = reader.ReadMeshGeometry(node);
    }
    reader.ReadDeformation(node, shape);
  }

  // The deformation is written with the fields all shapes have (it names shared parents).
  json Write(const Shape& shape) const override {
    if (shape.SharesMesh()) return json{{"mesh_ref", shape.meshRef}};
    return scene_write::MeshJson(shape.mesh, json::object());
  }

  void Translate(Shape& shape, const Vec3& offset) const override {
    if (shape.deformation && shape.deformation->hasSkin) {
      // Skinned vertices are in bind space, placed in the world by their joints: the
      // offset is added after skinning (a shared mesh is then moved twice over, so a
      // skinned shape keeps a copy of its own).
      auto deformation = std::make_shared<Deformation>(*shape.deformation);
      deformation->skin.worldOffset = Moved(deformation->skin.worldOffset, offset);
      shape.deformation = std::move(deformation);
      OwnMesh(shape);
      return;
    }
    // A shared mesh moves with the scene's table (TranslateScene), once for all its shapes.
    for (Vec3& v : shape.mesh.vertices) v = Moved(v, offset);
  }

  bool PlaceStill(Shape& shape, const Affine& placement) const override {
    PlaceTrianglesStill(shape, placement);
    return true;
  }
};

}  // namespace

const ShapeFormat& MeshFormat() {
  static const MeshFormatImpl format;
  return format;
}

}  // namespace tcfarm
