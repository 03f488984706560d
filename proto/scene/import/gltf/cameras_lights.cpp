// KHR_lights_punctual lights and the camera (or one framing the scene).
#include "proto/scene/import/gltf/gltf_reader.h"

namespace tcfarm::gltf {
namespace {

// "(x, y, z)", three significant digits each: enough for a person to picture it.
std::string Triple(const Vec3& v) {
  char text[96];
  std::snprintf(text, sizeof text, "(%.3g, %.3g, %.3g)", v.x, v.y, v.z);
  return text;
}

}  // namespace

void GltfReader::AddLights(Scene& scene) const {
  bool any = false;
  for (int node : order_) {
    const auto& source = model_.nodes[static_cast<size_t>(node)];
    auto extension = source.extensions.find("KHR_lights_punctual");
    if (extension == source.extensions.end() || !extension->second.Has("light")) continue;
    const std::string pointer = Pointer("nodes", static_cast<size_t>(node)) + "/extensions/KHR_lights_punctual/light";
    const tinygltf::Value& index = extension->second.Get("light");
    if (!index.IsInt() || index.GetNumberAsInt() < 0 ||
        static_cast<size_t>(index.GetNumberAsInt()) >= model_.lights.size()) {
      Fail(pointer, "no such light", "the index of a KHR_lights_punctual light");
    }
    const size_t lightIndex = static_cast<size_t>(index.GetNumberAsInt());
    const tinygltf::Light& light = model_.lights[lightIndex];
    const std::string lightPointer = "/extensions/KHR_lights_punctual/lights/" + std::to_string(lightIndex);
    std::vector<double> color = light.color.size() == 3 ? light.color : std::vector<double>{1, 1, 1};
    for (double v : {color[0], color[1], color[2], light.intensity}) {
      if (!(v >= 0 && v <= kMaxMagnitude))
        Fail(lightPointer, "a colour or intensity of " + std::to_string(v), "finite non-negative values");
    }
    Light out;
    if (light.type == "directional") {
      out.type = Light::Type::kDirectional;
      out.direction = AnimatedVec3::Constant({0, 0, -1});
    } else if (light.type == "point") {
      out.type = Light::Type::kPoint;
      out.position = AnimatedVec3::Constant({0, 0, 0});
    } else if (light.type == "spot") {
      // A spot shines down its node's -z; glTF's cone angles are radians from the axis.
      out.type = Light::Type::kSpot;
      out.position = AnimatedVec3::Constant({0, 0, 0});
      out.direction = AnimatedVec3::Constant({0, 0, -1});
      const double outer = light.spot.outerConeAngle * 180 / kPi, inner = light.spot.innerConeAngle * 180 / kPi;
      if (!(outer > 0 && outer <= 90)) {
        Fail(lightPointer + "/spot/outerConeAngle", std::to_string(light.spot.outerConeAngle), "an angle in (0, pi/2]");
      }
      if (!(inner >= 0 && inner < outer)) {
        Fail(lightPointer + "/spot/innerConeAngle", std::to_string(light.spot.innerConeAngle),
             "an angle in [0, outerConeAngle)");
      }
      out.outerConeDegrees = outer;
      out.innerConeDegrees = inner;
    } else {
      Fail(lightPointer + "/type", "type " + QuoteInput(light.type), "point, spot or directional");
    }
    // KHR_lights_punctual's candela and lux as watts per steradian and per square metre
    // (proto/scene.md, "glTF lights").
    const double watts = light.intensity * WattsPerLightUnit(options_.lightUnits);
    out.intensity = AnimatedVec3::Constant({color[0] * watts, color[1] * watts, color[2] * watts});
    if (light.type != "directional" && light.range > 0) {
      if (!(light.range <= kMaxMagnitude)) Fail(lightPointer + "/range", std::to_string(light.range), "a finite range");
      out.range = light.range;
    }
    out.motion = *motions_[static_cast<size_t>(node)];
    scene.lights.push_back(out);
    any = true;
  }
  if (!any) AddDefaultLight(scene);
}

void GltfReader::AddDefaultLight(Scene& scene) const {
  // kDefaultLightDirection in the camera's own axes (right, up, forward) at the first frame:
  // from above and behind its right shoulder, so what the camera sees is lit whichever way
  // the file's camera looks. For the default camera that is kDefaultLightDirection itself.
  Vec3 direction = kDefaultLightDirection;
  if (cameraFromFile_) {
    const CameraPose pose = scene.camera.At(0);
    const Vec3 forward = Normalized(Sub(pose.lookAt, pose.position));
    const Vec3 right = Normalized(CrossProduct(forward, pose.up));
    const Vec3 up = CrossProduct(right, forward);
    for (int axis = 0; axis < 3; ++axis) {
      direction[axis] = kDefaultLightDirection.x * right[axis] + kDefaultLightDirection.y * up[axis] -
                        kDefaultLightDirection.z * forward[axis];
    }
  }
  Light light;
  light.type = Light::Type::kDirectional;
  light.direction = AnimatedVec3::Constant(direction);
  // Irradiance pi: a white diffuse surface facing it shows white.
  light.intensity = AnimatedVec3::Constant(Vec3{kPi, kPi, kPi});
  scene.lights.push_back(light);
  Warn("default_light", "/extensions/KHR_lights_punctual",
       "the file has no light; one white directional light (irradiance pi) shines along " + Triple(direction) +
           ", from above and behind the camera's right shoulder");
}

void GltfReader::AddCamera(Scene& scene) {
  int chosenNode = -1;
  const std::string& wanted = options_.camera;
  for (int node : order_) {
    int camera = model_.nodes[static_cast<size_t>(node)].camera;
    if (camera < 0) continue;
    if (static_cast<size_t>(camera) >= model_.cameras.size()) {
      Fail(Pointer("nodes", static_cast<size_t>(node)) + "/camera",
           "camera " + std::to_string(camera) + " does not exist", "the index of a camera");
    }
    bool match = wanted.empty() || model_.nodes[static_cast<size_t>(node)].name == wanted ||
                 model_.cameras[static_cast<size_t>(camera)].name == wanted || std::to_string(camera) == wanted;
    // The first in node order, whatever order the depth-first walk met them.
    if (match && (chosenNode < 0 || node < chosenNode)) chosenNode = node;
  }
  if (chosenNode < 0 && !wanted.empty()) {
    Fail("/cameras", "no camera node named or numbered " + QuoteInput(wanted),
         "a camera's (or its node's) name, or its index");
  }
  if (chosenNode < 0) {
    FrameBounds(scene);
    return;
  }
  cameraFromFile_ = true;
  const size_t cameraIndex = static_cast<size_t>(model_.nodes[static_cast<size_t>(chosenNode)].camera);
  const tinygltf::Camera& camera = model_.cameras[cameraIndex];
  const std::string pointer = Pointer("cameras", cameraIndex);
  double degrees = 45;
  if (camera.type == "orthographic") {
    // ymag is half the view's height; the render size sets the width, as for yfov.
    const double ymag = camera.orthographic.ymag;
    if (!(ymag > 0 && ymag <= 5e8)) {
      Fail(pointer + "/orthographic/ymag", std::to_string(ymag), "a positive half height of the view");
    }
    scene.camera.orthographic = true;
    scene.camera.orthographicHeight = 2 * ymag;
  } else if (camera.type == "perspective") {
    degrees = camera.perspective.yfov * 180 / kPi;
    if (!(degrees > 0 && degrees < 180)) {
      Fail(pointer + "/perspective/yfov", std::to_string(camera.perspective.yfov) + " radians",
           "a field of view in (0, pi)");
    }
  } else {
    Fail(pointer + "/type", "type " + QuoteInput(camera.type), "perspective or orthographic");
  }
  // glTF cameras look down their node's -z with +y up; the node's motion carries them.
  scene.camera.position = AnimatedVec3::Constant({0, 0, 0});
  scene.camera.lookAt = AnimatedVec3::Constant({0, 0, -1});
  scene.camera.up = {0, 1, 0};
  scene.camera.verticalFovDegrees = degrees;
  scene.camera.rig = *motions_[static_cast<size_t>(chosenNode)];
}

import::BoundingBox GltfReader::AnimationBounds(const Scene& scene) const {
  // Every frame, or evenly spaced ones when deforming every vertex at every frame would
  // cost more than kFramingVertexBudget vertex evaluations; the framing margin covers the rest.
  size_t deformed = 0;
  for (const Shape& shape : scene.shapes) deformed += shape.deformation ? shape.Mesh().vertices.size() : 0;
  const size_t frames = static_cast<size_t>(frameCount_);
  const size_t step = std::max<size_t>(1, deformed * frames / kFramingVertexBudget);
  std::vector<double> framed;
  for (size_t frame = 0; frame < frames; frame += step) framed.push_back(static_cast<double>(frame));
  if (framed.back() != static_cast<double>(frames - 1)) framed.push_back(static_cast<double>(frames - 1));
  // A rigid shape's box, once: its corners placed at each frame bound it there.
  std::vector<std::array<Vec3, 8>> corners(scene.shapes.size());
  for (size_t i = 0; i < scene.shapes.size(); ++i) {
    import::BoundingBox box;
    if (!scene.shapes[i].deformation) box.Add(scene.shapes[i].Mesh().vertices);
    corners[i] = box.Corners();
  }
  import::BoundingBox bounds;
  for (double at : framed) {
    for (size_t i = 0; i < scene.shapes.size(); ++i) {
      const Shape& shape = scene.shapes[i];
      if (shape.deformation) {  // placed by its joints alone: its deformed vertices are in the world
        bounds.Add(Deform(shape.Mesh(), *shape.deformation, at).positions);
        continue;
      }
      const Affine worldFromObject = shape.motion.WorldFromObject(at);
      for (const Vec3& corner : corners[i]) bounds.Add(worldFromObject.Apply(corner));
    }
  }
  return bounds;
}

void GltfReader::FrameBounds(Scene& scene) const {
  const CameraPose pose = import::FramingPose(AnimationBounds(scene), input_.displayName);
  scene.camera.position = AnimatedVec3::Constant(pose.position);
  scene.camera.lookAt = AnimatedVec3::Constant(pose.lookAt);
  scene.camera.verticalFovDegrees = import::kFramingFovDegrees;
  Warn("default_camera", "/cameras",
       "the file has no camera; one at " + Triple(pose.position) + " looks at " + Triple(pose.lookAt) +
           " from the front and above, framing the model's bounds " +
           (frameCount_ == 1 ? std::string("at its one frame")
                             : "over all " + std::to_string(frameCount_) + " frames of the animation"));
}

}  // namespace tcfarm::gltf
