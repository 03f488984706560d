// Reading a scene's shapes: the fields every shape has; each kind reads its own
// (proto/scene/shapes/).
#include "proto/scene/parse/scene_reader.h"
#include "proto/scene/shapes/shape_format.h"

namespace tcfarm::scene_parse {

std::vector<Shape> SceneReader::ReadShapes(const Node& node) {
  if (!node.value.is_array()) FailType(node, "an array of shapes");
  std::vector<Shape> shapes;
  for (size_t i = 0; i < node.value.size(); ++i) shapes.push_back(ReadShape(node.Element(i)));
  return shapes;
}

Shape SceneReader::ReadShape(const Node& node) {
  const std::string typeExpected = ShapeTypeChoices();
  if (!node.value.is_object()) FailType(node, "a shape {\"type\": " + typeExpected + ", ...}");
  std::string typeName = ReadString(Required(node, "type", typeExpected), typeExpected);
  const std::optional<Shape::Type> type = FindShapeType(typeName);
  if (!type) Fail(node.MemberPointer("type"), "unknown shape type " + Quote(typeName), typeExpected);
  Shape shape;
  shape.type = *type;
  FormatOf(*type).Read(*this, node, shape);
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

}  // namespace tcfarm::scene_parse
