// Reading a scene's camera, and the fields every light has; each kind of light reads its
// own (proto/scene/lights/).
#include "proto/scene/lights/light_format.h"
#include "proto/scene/parse/scene_reader.h"

namespace tcfarm::scene_parse {

Camera SceneReader::ReadCamera(const Node& node) {
  ExpectObject(node, {"position", "look_at", "up", "fov_degrees", "motion", "projection", "ortho_height"}, "a camera");
  Camera camera;
  if (node.Has("motion")) camera.rig = ReadMotion(node.Member("motion"), range_, 0, &named_);
  camera.position = ReadAnimated(Required(node, "position", kAnimatedExpected), range_);
  camera.lookAt = ReadAnimated(Required(node, "look_at", kAnimatedExpected), range_);
  if (node.Has("up")) camera.up = ReadVec3(node.Member("up"));
  if (IsZeroLength(camera.up)) Fail(node.MemberPointer("up"), "zero-length up vector", "a non-zero up direction");
  if (node.Has("fov_degrees")) {
    Node fov = node.Member("fov_degrees");
    camera.verticalFovDegrees = ReadNumber(fov, "a vertical field of view in (0, 180) degrees");
    if (camera.verticalFovDegrees <= 0 || camera.verticalFovDegrees >= 180) {
      Fail(fov.pointer, Show(fov.value) + " is out of range", "a vertical field of view in (0, 180) degrees");
    }
  }
  ReadProjection(node, camera);
  CheckCameraBasis(camera, node);
  return camera;
}

void SceneReader::ReadProjection(const Node& node, Camera& camera) const {
  const std::string expected = "\"perspective\" or \"orthographic\"";
  if (node.Has("projection")) {
    Node projection = node.Member("projection");
    const std::string name = ReadString(projection, expected);
    if (name != "perspective" && name != "orthographic") {
      Fail(projection.pointer, "unknown projection " + Quote(name), expected);
    }
    camera.orthographic = name == "orthographic";
  }
  if (node.Has("ortho_height")) {
    Node height = node.Member("ortho_height");
    if (!camera.orthographic) {
      Fail(height.pointer, "an orthographic height for a perspective camera", "ortho_height only with \"projection\": \"orthographic\"");
    }
    camera.orthographicHeight = ReadInRange(height, 1e-9, 1e9, "a positive height of the image plane in [1e-9, 1e9]");
  }
}

void SceneReader::CheckCameraBasis(const Camera& camera, const Node& node) const {
  for (double frame : AllFrames(camera.Moves(), range_)) {
    const CameraPose pose = camera.At(frame);
    const Vec3& position = pose.position;
    const Vec3& lookAt = pose.lookAt;
    Vec3 view = Subtract(lookAt, position);
    if (IsZeroLength(view) || Length(view) <= kMinViewRatio * std::max(MaxAbs(position), MaxAbs(lookAt))) {
      Fail(node.MemberPointer("look_at"), "look_at equals position " + FormatVec3(position) + " at frame " +
                                              FormatNumber(frame),
           "a look_at point distinct from the camera position at every frame");
    }
    if (Length(Cross(view, pose.up)) <= kMinUpSine * Length(view) * Length(pose.up)) {
      Fail(node.MemberPointer("up"), "up " + FormatVec3(pose.up) + " is parallel to the view direction " +
                                         FormatVec3(view) + " at frame " + FormatNumber(frame),
           "an up vector not parallel to the view direction");
    }
  }
}

std::vector<Light> SceneReader::ReadLights(const Node& node) {
  if (!node.value.is_array()) FailType(node, "an array of lights");
  std::vector<Light> lights;
  for (size_t i = 0; i < node.value.size(); ++i) lights.push_back(ReadLight(node.Element(i)));
  return lights;
}

Light SceneReader::ReadLight(const Node& node) {
  const std::string typeExpected = LightTypeChoices();
  if (!node.value.is_object()) FailType(node, "a light {\"type\": " + typeExpected + ", ...}");
  std::string typeName = ReadString(Required(node, "type", typeExpected), typeExpected);
  const std::optional<Light::Type> type = FindLightType(typeName);
  if (!type) Fail(node.MemberPointer("type"), "unknown light type " + Quote(typeName), typeExpected);
  Light light;
  light.type = *type;
  FormatOf(*type).Read(*this, node, light);
  if (node.Has("motion")) light.motion = ReadMotion(node.Member("motion"), range_, 0, &named_);
  // Only the kinds that take a range let it through their fields.
  if (node.Has("range")) {
    light.range = ReadInRange(node.Member("range"), 0, kMaxMagnitude, "a range >= 0 in scene units (0: no limit)");
  }
  Node intensity = Required(node, "intensity", kAnimatedExpected);
  light.intensity = ReadAnimated(intensity, range_);
  CheckNonNegative(light.intensity, intensity, range_);
  return light;
}

AnimatedVec3 SceneReader::ReadLightPosition(const Node& light) const {
  return ReadAnimated(Required(light, "position", kAnimatedExpected), range_);
}

AnimatedVec3 SceneReader::ReadLightDirection(const Node& light) const {
  Node direction = Required(light, "direction", kAnimatedExpected);
  AnimatedVec3 value = ReadAnimated(direction, range_);
  CheckDirection(value, direction);
  return value;
}

void SceneReader::CheckDirection(const AnimatedVec3& direction, const Node& node) const {
  for (double frame : AllFrames(direction.IsAnimated(), range_)) {
    if (IsZeroLength(direction.Evaluate(frame))) {
      Fail(node.pointer, "zero-length direction at frame " + FormatNumber(frame), "a non-zero direction");
    }
  }
}

}  // namespace tcfarm::scene_parse
