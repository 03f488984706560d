// The table of shape kinds, built from TCFARM_SHAPE_KINDS in Shape::Type's order.
#include "proto/scene/shapes/shape_format.h"

#include <array>
#include <utility>

#include "proto/scene/kind_table.h"

namespace tcfarm {
namespace {

const std::array<const ShapeFormat*, Shape::kTypeCount>& Formats() {
#define TCFARM_SHAPE_FORMAT_ENTRY(Stem) &Stem##Format(),
  static const std::array<const ShapeFormat*, Shape::kTypeCount> formats{TCFARM_SHAPE_KINDS(TCFARM_SHAPE_FORMAT_ENTRY)};
#undef TCFARM_SHAPE_FORMAT_ENTRY
  return formats;
}

}  // namespace

const ShapeFormat& FormatOf(Shape::Type type) { return *Formats().at(static_cast<size_t>(type)); }

std::optional<Shape::Type> FindShapeType(const std::string& name) {
  const std::optional<size_t> index = FindKindIndex(Formats(), name);
  return index ? std::optional(static_cast<Shape::Type>(*index)) : std::nullopt;
}

const std::string& ShapeTypeChoices() {
  static const std::string choices = KindChoices(Formats());
  return choices;
}

void OwnMesh(Shape& shape) {
  if (!shape.SharesMesh()) return;
  shape.mesh = *shape.sharedMesh;
  shape.sharedMesh.reset();
  shape.meshRef.clear();
}

void PlaceTrianglesStill(Shape& shape, const Affine& placement) {
  // A still placement is built into world-space triangles of its own, as an inline copy
  // would be (see PlaceStillShapes in scene.h): its normals go to the world too.
  OwnMesh(shape);
  for (Vec3& v : shape.mesh.vertices) v = placement.Apply(v);
  double normalMatrix[3][3];
  placement.NormalMatrix(normalMatrix);
  for (Vec3& n : shape.mesh.normals) n = ApplyMatrix(normalMatrix, n);
  // Tangents are directions on the surface: they move as its edges do. A mirror turns the
  // bitangent over.
  for (auto& tangent : shape.mesh.tangents) {
    const Vec3 moved = placement.ApplyLinear({tangent[0], tangent[1], tangent[2]});
    tangent = {moved.x, moved.y, moved.z, placement.Determinant() < 0 ? -tangent[3] : tangent[3]};
  }
  // A mirror turns the triangles' winding over, and with it the face normals the tracer
  // takes from it: turned back, the outside stays outside (as glTF has it).
  if (placement.Determinant() < 0) {
    for (auto& triangle : shape.mesh.triangles) std::swap(triangle[1], triangle[2]);
  }
}

}  // namespace tcfarm
