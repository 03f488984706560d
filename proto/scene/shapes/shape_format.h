// What the scene format knows of one kind of shape, behind one interface: how it is read
// from scene JSON and written back, and how it moves with the world (TranslateScene,
// PlaceStillShapes). One file per kind here (sphere.cpp, quad.cpp, mesh.cpp, terrain.cpp),
// each defining the <Stem>Format() that TCFARM_SHAPE_KINDS (scene.h) names; the reader,
// the writer and scene.cpp find a kind through FormatOf and FindShapeType alone.
#pragma once

#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "proto/scene/scene.h"

namespace tcfarm {

namespace scene_parse {
class SceneReader;
struct Node;
}  // namespace scene_parse

class ShapeFormat {
 public:
  virtual ~ShapeFormat() = default;
  // The kind's "type" in scene JSON.
  virtual const char* Name() const = 0;
  // Reads the kind's own fields of `node` into `shape`, refusing any other key but the
  // fields every shape has (SceneReader::ShapeFields); the reader reads those after.
  virtual void Read(scene_parse::SceneReader& reader, const scene_parse::Node& node, Shape& shape) const = 0;
  // Work left until the whole scene is known to be valid (a rejected scene should cost no
  // geometry): terrain generates its mesh here.
  virtual void Complete(Shape&, const Checkpoint&) const {}
  // The kind's own fields as the parser reads them back ("type" and the common fields are
  // the writer's).
  virtual nlohmann::json Write(const Shape& shape) const = 0;
  // Moves the shape's rest pose by `offset` with the world (its motion is the caller's).
  virtual void Translate(Shape& shape, const Vec3& offset) const = 0;
  // Builds the constant `placement` into the rest pose; false where the kind cannot hold
  // it (a sphere scaled unevenly), the shape then left as it was.
  virtual bool PlaceStill(Shape& shape, const Affine& placement) const = 0;
};

#define TCFARM_DECLARE_SHAPE_FORMAT(Stem) const ShapeFormat& Stem##Format();
TCFARM_SHAPE_KINDS(TCFARM_DECLARE_SHAPE_FORMAT)
#undef TCFARM_DECLARE_SHAPE_FORMAT

const ShapeFormat& FormatOf(Shape::Type type);

// The type a scene's "type" names; none for a name no kind has.
std::optional<Shape::Type> FindShapeType(const std::string& name);

// Every kind's name, for messages: "\"sphere\", \"quad\", \"mesh\" or \"terrain\"".
const std::string& ShapeTypeChoices();

// --- shared by the kinds ---

inline Vec3 Moved(const Vec3& point, const Vec3& offset) {
  return {point.x + offset.x, point.y + offset.y, point.z + offset.z};
}

// Gives a shape placing a shared mesh a copy of its own (to change its vertices alone).
void OwnMesh(Shape& shape);

// Builds a constant placement into a triangle mesh shape's own copy of its triangles (a
// mesh's, a terrain's).
void PlaceTrianglesStill(Shape& shape, const Affine& placement);

}  // namespace tcfarm
