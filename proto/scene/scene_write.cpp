// Scene -> scene JSON, in the canonical form the parser reads back (scene_parse.cpp).
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "proto/scene/scene.h"
#include "proto/scene/scene_write.h"
#include "proto/scene/lights/light_format.h"
#include "proto/scene/materials/material_format.h"
#include "proto/scene/shapes/shape_format.h"

namespace tcfarm {

using nlohmann::json;

json scene_write::Vec3Json(const Vec3& v) { return json::array({v.x, v.y, v.z}); }

json scene_write::TextureJson(const Texture& texture) {
  static const char* const kWraps[] = {"repeat", "clamp_to_edge", "mirrored_repeat"};
  json result{{texture.asset.empty() ? "image" : "asset", texture.asset.empty() ? texture.image : texture.asset},
              {"wrap_s", kWraps[static_cast<int>(texture.wrapS)]},
              {"wrap_t", kWraps[static_cast<int>(texture.wrapT)]},
              {"filter", texture.filter == Texture::Filter::kNearest ? "nearest" : "linear"}};
  // Written only when off: scenes written before it existed keep their bytes (and hashes).
  if (!texture.mipmaps) result["mipmaps"] = false;
  return result;
}

namespace {

using scene_write::AnimatedJson;
using scene_write::MeshJson;
using scene_write::Vec3Json;

// --- writing -------------------------------------------------------------------------

// Linear, the default, is left out: scenes written before splines keep their bytes.
json WithInterpolation(json keyed, Interpolation interpolation) {
  if (interpolation == Interpolation::kStep) keyed["interpolation"] = "step";
  if (interpolation == Interpolation::kCubicSpline) keyed["interpolation"] = "cubicspline";
  return keyed;
}

}  // namespace

json scene_write::AnimatedJson(const AnimatedVec3& value) {
  switch (value.kind()) {
    case AnimatedVec3::Kind::kConstant:
      return Vec3Json(value.constant());
    case AnimatedVec3::Kind::kPolynomial: {
      json axes = json::array();
      for (const auto& axis : value.coefficients()) axes.push_back(axis);
      return json{{"polynomial", axes}};
    }
    case AnimatedVec3::Kind::kKeyframes: {
      const bool cubic = value.interpolation() == Interpolation::kCubicSpline;
      json keys = json::array();
      for (const auto& key : value.keys()) {
        json entry{{"frame", key.frame}, {"value", Vec3Json(key.value)}};
        if (cubic) entry["in_tangent"] = Vec3Json(key.inTangent), entry["out_tangent"] = Vec3Json(key.outTangent);
        keys.push_back(std::move(entry));
      }
      return WithInterpolation(json{{"keyframes", keys}}, value.interpolation());
    }
  }
  return Vec3Json(value.constant());
}

namespace {

json QuaternionJson(const Quaternion& q) { return json::array({q.x, q.y, q.z, q.w}); }

json RotationJson(const AnimatedRotation& rotation) {
  switch (rotation.kind()) {
    case AnimatedRotation::Kind::kConstant:
      return QuaternionJson(rotation.constant());
    case AnimatedRotation::Kind::kKeyframes: {
      const bool cubic = rotation.interpolation() == Interpolation::kCubicSpline;
      json keys = json::array();
      for (const auto& key : rotation.keys()) {
        json entry{{"frame", key.frame}, {"value", QuaternionJson(key.value)}};
        if (cubic) entry["in_tangent"] = QuaternionJson(key.inTangent), entry["out_tangent"] = QuaternionJson(key.outTangent);
        keys.push_back(std::move(entry));
      }
      return WithInterpolation(json{{"keyframes", keys}}, rotation.interpolation());
    }
    case AnimatedRotation::Kind::kSpin:
      return json{{"axis", Vec3Json(rotation.axis())},
                  {"degrees_per_frame", rotation.degreesPerFrame()},
                  {"degrees", rotation.degreesAtZero()}};
  }
  return json::array();
}

// A translation alone is written as the paper's motion always was, so the text (and the
// hash) of a scene without rotation or scale does not change.
// The parents that several transforms share (by object: a glTF node's, or a named
// transform's), written once in "transforms" and named by the transforms they carry. A
// parent of one transform stays inline, so a scene without shared parents keeps its bytes.
class SharedParents {
 public:
  explicit SharedParents(const Scene& scene) {
    Visit(scene.camera.rig);
    for (const Light& light : scene.lights) Visit(light.motion);
    for (const Shape& shape : scene.shapes) {
      Visit(shape.motion);
      if (shape.deformation && shape.deformation->hasSkin) {
        for (const Motion& joint : shape.deformation->skin.joints) Visit(joint);
      }
    }
    for (const Motion* parent : order_) {
      if (uses_[parent] > 1) names_[parent] = "t" + std::to_string(names_.size());
    }
  }
  // The name a shared parent is written under; null for one written inline.
  const std::string* NameOf(const Motion* parent) const {
    auto found = names_.find(parent);
    return found == names_.end() ? nullptr : &found->second;
  }
  // "transforms": each shared parent, in the order first met.
  json Table() const;

 private:
  void Visit(const Motion& motion) {
    const Motion* parent = motion.parent.get();
    if (!parent || parent->IsNone()) return;
    if (uses_[parent]++ == 0) {
      order_.push_back(parent);
      Visit(*parent);  // its own parent is counted once, however many carry it
    }
  }
  std::map<const Motion*, int> uses_;
  std::vector<const Motion*> order_;
  std::map<const Motion*, std::string> names_;
};

json TransformJson(const Motion& motion, const SharedParents& shared) {
  json result{{"translation", AnimatedJson(motion.translation)},
              {"rotation", RotationJson(motion.rotation)},
              {"scale", AnimatedJson(motion.scale)},
              {"pivot", Vec3Json(motion.pivot)}};
  if (motion.parent && !motion.parent->IsNone()) {
    const std::string* name = shared.NameOf(motion.parent.get());
    result["parent"] = name ? json(*name) : TransformJson(*motion.parent, shared);
  }
  return result;
}

json SharedParents::Table() const {
  json table = json::object();
  for (const Motion* parent : order_) {
    if (const std::string* name = NameOf(parent)) table[*name] = TransformJson(*parent, *this);
  }
  return table;
}

json MotionJson(const Motion& motion, const SharedParents& shared) {
  return motion.IsTranslationOnly() ? AnimatedJson(motion.translation) : TransformJson(motion, shared);
}

json CameraJson(const Camera& camera, const SharedParents& shared) {
  json result{{"position", AnimatedJson(camera.position)},
              {"look_at", AnimatedJson(camera.lookAt)},
              {"up", Vec3Json(camera.up)},
              {"fov_degrees", camera.verticalFovDegrees}};
  if (camera.orthographic) result["projection"] = "orthographic", result["ortho_height"] = camera.orthographicHeight;
  if (!camera.rig.IsNone()) result["motion"] = MotionJson(camera.rig, shared);
  return result;
}

json LightJson(const Light& light, const SharedParents& shared) {
  const LightFormat& format = FormatOf(light.type);
  json result = format.Write(light);
  result["type"] = format.Name();
  result["intensity"] = AnimatedJson(light.intensity);
  if (light.range > 0) result["range"] = light.range;
  if (!light.motion.IsNone()) result["motion"] = MotionJson(light.motion, shared);
  return result;
}


json MaterialJson(const Material& material) { return MaterialFormatOf(material).Write(material); }

}  // namespace

json scene_write::MeshJson(const TriangleMesh& mesh, json result) {
  json vertices = json::array();
  for (const auto& v : mesh.vertices) vertices.push_back(Vec3Json(v));
  json triangles = json::array();
  for (const auto& t : mesh.triangles) triangles.push_back(json::array({t[0], t[1], t[2]}));
  result["vertices"] = std::move(vertices);
  result["triangles"] = std::move(triangles);
  if (!mesh.normals.empty()) {
    json normals = json::array();
    for (const auto& n : mesh.normals) normals.push_back(Vec3Json(n));
    result["normals"] = std::move(normals);
  }
  if (!mesh.uvs.empty()) {
    json uvs = json::array();
    for (const auto& uv : mesh.uvs) uvs.push_back(json::array({uv[0], uv[1]}));
    result["uvs"] = std::move(uvs);
  }
  if (!mesh.uvs1.empty()) {
    json uvs = json::array();
    for (const auto& uv : mesh.uvs1) uvs.push_back(json::array({uv[0], uv[1]}));
    result["uvs1"] = std::move(uvs);
  }
  if (!mesh.tangents.empty()) {
    json tangents = json::array();
    for (const auto& t : mesh.tangents) tangents.push_back(json::array({t[0], t[1], t[2], t[3]}));
    result["tangents"] = std::move(tangents);
  }
  if (!mesh.colors.empty()) {
    json colors = json::array();
    for (const auto& c : mesh.colors) colors.push_back(Vec3Json(c));
    result["colors"] = std::move(colors);
  }
  return result;
}

namespace {

// The kind's own fields (its format's), with its "type".
json ShapeGeometryJson(const Shape& shape) {
  const ShapeFormat& format = FormatOf(shape.type);
  json result = format.Write(shape);
  result["type"] = format.Name();
  return result;
}

json WeightsJson(const AnimatedWeights& weights) {
  if (weights.IsConstant()) return weights.constant();
  const bool cubic = weights.interpolation() == Interpolation::kCubicSpline;
  json keys = json::array();
  for (const auto& key : weights.keys()) {
    json entry{{"frame", key.frame}, {"value", key.values}};
    if (cubic) entry["in_tangent"] = key.inTangent, entry["out_tangent"] = key.outTangent;
    keys.push_back(std::move(entry));
  }
  return WithInterpolation(json{{"keyframes", keys}}, weights.interpolation());
}

json Vec3ListJson(const std::vector<Vec3>& values) {
  json list = json::array();
  for (const Vec3& v : values) list.push_back(Vec3Json(v));
  return list;
}

json MorphJson(const MorphTargets& morph) {
  json targets = json::array();
  for (size_t t = 0; t < morph.TargetCount(); ++t) {
    json target{{"positions", Vec3ListJson(morph.positionDeltas[t])}};
    if (!morph.normalDeltas[t].empty()) target["normals"] = Vec3ListJson(morph.normalDeltas[t]);
    targets.push_back(std::move(target));
  }
  return json{{"targets", std::move(targets)}, {"weights", WeightsJson(morph.weights)}};
}

json SkinJson(const Skin& skin, const SharedParents& shared) {
  json joints = json::array(), matrices = json::array(), vertexJoints = json::array(), vertexWeights = json::array();
  for (const Motion& joint : skin.joints) joints.push_back(MotionJson(joint, shared));
  for (const Affine& m : skin.inverseBind) {
    json matrix = json::array();
    for (int row = 0; row < 3; ++row) {
      matrix.insert(matrix.end(), {m.linear[row][0], m.linear[row][1], m.linear[row][2], m.offset[row]});
    }
    matrices.push_back(std::move(matrix));
  }
  const size_t k = static_cast<size_t>(skin.influencesPerVertex);
  for (size_t v = 0; v * k < skin.vertexJoints.size(); ++v) {
    vertexJoints.push_back(std::vector<uint32_t>(skin.vertexJoints.begin() + v * k, skin.vertexJoints.begin() + (v + 1) * k));
    vertexWeights.push_back(std::vector<double>(skin.vertexWeights.begin() + v * k, skin.vertexWeights.begin() + (v + 1) * k));
  }
  json result{{"joints", std::move(joints)},
              {"inverse_bind_matrices", std::move(matrices)},
              {"vertex_joints", std::move(vertexJoints)},
              {"vertex_weights", std::move(vertexWeights)}};
  if (skin.worldOffset != Vec3{}) result["offset"] = Vec3Json(skin.worldOffset);
  return result;
}

json ShapeJson(const Shape& shape, const std::vector<Material>& materials, const SharedParents& shared) {
  json result = ShapeGeometryJson(shape);
  if (shape.deformation && shape.deformation->hasMorph) result["morph"] = MorphJson(shape.deformation->morph);
  if (shape.deformation && shape.deformation->hasSkin) result["skin"] = SkinJson(shape.deformation->skin, shared);
  if (!shape.name.empty()) result["name"] = shape.name;
  result["material"] = materials.at(static_cast<size_t>(shape.material)).name;
  // A skinned mesh has no motion of its own (its joints place it), and the parser refuses one.
  if (!(shape.deformation && shape.deformation->hasSkin)) result["motion"] = MotionJson(shape.motion, shared);
  return result;
}

json SharedMeshesJson(const std::map<std::string, std::shared_ptr<const TriangleMesh>>& meshes) {
  json result = json::object();
  for (const auto& [name, mesh] : meshes) result[name] = MeshJson(*mesh, json::object());
  return result;
}

json RenderJson(const RenderSettings& render) {
  json result{{"width", render.width},
              {"height", render.height},
              {"frames", {{"start", render.firstFrame}, {"count", render.frameCount}}},
              {"samples_per_pixel", render.samplesPerPixel},
              {"max_depth", render.maxDepth}};
  // Written only when switched: a scene that leaves them keeps the bytes (and hash) it had.
  if (!render.shadows) result["shadows"] = false;
  if (render.ambient != RenderSettings::kDefaultAmbient) result["ambient"] = render.ambient;
  return result;
}

}  // namespace

std::string SerializeScene(const Scene& scene) {
  const SharedParents shared(scene);
  json materials = json::object();
  for (const auto& material : scene.materials) materials[material.name] = MaterialJson(material);
  json lights = json::array();
  for (const auto& light : scene.lights) lights.push_back(LightJson(light, shared));
  json shapes = json::array();
  for (const auto& shape : scene.shapes) shapes.push_back(ShapeJson(shape, scene.materials, shared));
  json document{{"camera", CameraJson(scene.camera, shared)}, {"lights", lights},
                {"materials", materials},             {"shapes", shapes},
                {"background", Vec3Json(scene.background)}, {"render", RenderJson(scene.render)}};
  // Only scenes with shared meshes have the key: every other scene keeps its bytes (and hash).
  if (!scene.meshes.empty()) document["meshes"] = SharedMeshesJson(scene.meshes);
  if (json table = shared.Table(); !table.empty()) document["transforms"] = std::move(table);
  return document.dump();
}

}  // namespace tcfarm
