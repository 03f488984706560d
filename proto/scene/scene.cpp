#include "proto/scene/scene.h"

#include <algorithm>
#include <memory>
#include <utility>

#include "proto/scene/lights/light_format.h"
#include "proto/scene/shapes/shape_format.h"

namespace tcfarm {

CameraPose Camera::At(double frame) const {
  CameraPose pose{position.Evaluate(frame), lookAt.Evaluate(frame), up};
  if (rig.IsNone()) return pose;  // the common case: inputs untouched, bits kept
  const Affine worldFromRig = rig.WorldFromObject(frame);
  return {worldFromRig.Apply(pose.position), worldFromRig.Apply(pose.lookAt), worldFromRig.ApplyLinear(pose.up)};
}

Vec3 Light::PositionAt(double frame) const {
  Vec3 p = position.Evaluate(frame);
  return motion.IsNone() ? p : motion.WorldFromObject(frame).Apply(p);
}

Vec3 Light::DirectionAt(double frame) const {
  Vec3 d = direction.Evaluate(frame);
  return motion.IsNone() ? d : motion.WorldFromObject(frame).ApplyLinear(d);
}

bool Light::HasPosition() const { return FormatOf(type).HasPosition(); }

bool Light::HasDirection() const { return FormatOf(type).HasDirection(); }

bool Light::SameAt(double a, double b) const {
  return PositionAt(a) == PositionAt(b) && DirectionAt(a) == DirectionAt(b) && intensity.SameAt(a, b);
}

bool Scene::CameraMoves() const { return camera.Moves(); }

bool Scene::AnyLightChanges() const {
  return std::any_of(lights.begin(), lights.end(), [](const Light& light) { return light.Changes(); });
}

bool Scene::AnyShapeMoves() const {
  return std::any_of(shapes.begin(), shapes.end(), [](const Shape& shape) { return shape.Moves(); });
}

bool Scene::AnyMaterialReflects() const {
  return std::any_of(materials.begin(), materials.end(),
                     [](const Material& material) { return material.Reflects(); });
}

bool Scene::AnyMaterialRefracts() const {
  return std::any_of(materials.begin(), materials.end(),
                     [](const Material& material) { return material.Refracts(); });
}

SceneError::SceneError(std::string pointer, const std::string& message)
    : std::runtime_error("scene" + pointer + ": " + message), pointer_(std::move(pointer)) {}

namespace {

Vec3 Plus(const Vec3& a, const Vec3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }

// A motion moved with the world: what it turns and scales turns about the moved pivot.
// A translation-only motion needs nothing, being relative to its object's place.
// With parents, T(o) P L T(-o) = [T(o) P T(-o)] [T(o) L T(-o)]: every level moves.
void OffsetPivot(Motion& motion, const Vec3& offset) {
  if (!motion.LocalIsTranslationOnly()) motion.pivot = Plus(motion.pivot, offset);
  if (motion.parent) {
    auto parent = std::make_shared<Motion>(*motion.parent);
    OffsetPivot(*parent, offset);
    motion.parent = std::move(parent);
  }
}

}  // namespace

namespace {

// Shared meshes move once, by the same offset an inline copy would: every shape placing
// one sees the bits its inline twin would. The moved meshes are new (the old ones may be
// shared with other copies of the scene).
void OffsetSharedMeshes(Scene& scene, const Vec3& offset) {
  for (auto& [name, shared] : scene.meshes) {
    auto moved = std::make_shared<TriangleMesh>(*shared);
    for (Vec3& v : moved->vertices) v = Plus(v, offset);
    shared = std::move(moved);
  }
  for (Shape& shape : scene.shapes) {
    if (shape.SharesMesh()) shape.sharedMesh = scene.meshes.at(shape.meshRef);
  }
}

}  // namespace

void TranslateScene(Scene& scene, const Vec3& offset) {
  scene.camera.position = Offset(scene.camera.position, offset);
  scene.camera.lookAt = Offset(scene.camera.lookAt, offset);
  OffsetPivot(scene.camera.rig, offset);
  for (Light& light : scene.lights) {
    OffsetPivot(light.motion, offset);
    FormatOf(light.type).Translate(light, offset);
  }
  for (Shape& shape : scene.shapes) {
    OffsetPivot(shape.motion, offset);
    FormatOf(shape.type).Translate(shape, offset);
  }
  OffsetSharedMeshes(scene, offset);
}

namespace {

// A skin or morph that never changes is applied once, and the shape becomes a rigid mesh.
void BakeStillDeformation(Shape& shape, int frame) {
  if (!shape.deformation || shape.deformation->IsAnimated()) return;
  DeformedVertices deformed = Deform(shape.Mesh(), *shape.deformation, frame);
  OwnMesh(shape);
  shape.mesh.vertices = std::move(deformed.positions);
  shape.mesh.normals = std::move(deformed.normals);
  shape.deformation.reset();
}

}  // namespace

void PlaceStillShapes(Scene& scene) {
  for (Shape& shape : scene.shapes) {
    BakeStillDeformation(shape, scene.render.firstFrame);
    if (shape.Moves() || shape.motion.IsNone()) continue;
    if (FormatOf(shape.type).PlaceStill(shape, shape.motion.WorldFromObject(scene.render.firstFrame))) {
      shape.motion = Motion{};
    }
  }
}

void PrepareForTracing(Scene& scene) {
  RebaseOnCamera(scene);
  PlaceStillShapes(scene);
}

void RebaseOnCamera(Scene& scene) {
  const Vec3 camera = scene.camera.At(scene.render.firstFrame).position;
  TranslateScene(scene, {-camera.x, -camera.y, -camera.z});
}

}  // namespace tcfarm
