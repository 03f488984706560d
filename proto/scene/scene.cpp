#include "proto/scene/scene.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <utility>

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

AnimatedVec3 Offset(const AnimatedVec3& value, const Vec3& offset) {
  switch (value.kind()) {
    case AnimatedVec3::Kind::kConstant:
      return AnimatedVec3::Constant(Plus(value.constant(), offset));
    case AnimatedVec3::Kind::kPolynomial: {
      auto coefficients = value.coefficients();
      coefficients[0][0] += offset.x;
      coefficients[1][0] += offset.y;
      coefficients[2][0] += offset.z;
      return AnimatedVec3::Polynomial(coefficients);
    }
    case AnimatedVec3::Kind::kKeyframes: {
      auto keys = value.keys();
      for (auto& key : keys) key.value = Plus(key.value, offset);
      return AnimatedVec3::Keyframes(keys);
    }
  }
  return value;
}

}  // namespace

namespace {

// Gives a shape placing a shared mesh a copy of its own (to change its vertices alone).
void OwnMesh(Shape& shape) {
  if (!shape.SharesMesh()) return;
  shape.mesh = *shape.sharedMesh;
  shape.sharedMesh.reset();
  shape.meshRef.clear();
}

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
    if (light.HasPosition()) light.position = Offset(light.position, offset);
    OffsetPivot(light.motion, offset);
  }
  for (Shape& shape : scene.shapes) {
    OffsetPivot(shape.motion, offset);
    shape.center = Plus(shape.center, offset);
    shape.corner = Plus(shape.corner, offset);
    shape.terrain.origin = Plus(shape.terrain.origin, offset);
    if (shape.deformation && shape.deformation->hasSkin) {
      // Skinned vertices are in bind space, placed in the world by their joints: the
      // offset is added after skinning (a shared mesh is then moved twice over, so a
      // skinned shape keeps a copy of its own).
      auto deformation = std::make_shared<Deformation>(*shape.deformation);
      deformation->skin.worldOffset = Plus(deformation->skin.worldOffset, offset);
      shape.deformation = std::move(deformation);
      OwnMesh(shape);
      continue;
    }
    for (Vec3& v : shape.mesh.vertices) v = Plus(v, offset);
  }
  OffsetSharedMeshes(scene, offset);
}

namespace {

// Whether the linear part is a rotation times one scale factor (then a sphere stays a
// sphere): its columns orthogonal and of equal length.
bool IsUniform(const Affine& placement) {
  const auto& m = placement.linear;
  auto column = [&](int c) { return Vec3{m[0][c], m[1][c], m[2][c]}; };
  auto dot = [](const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; };
  const double lengthSquared = dot(column(0), column(0));
  const double tolerance = 1e-12 * lengthSquared;
  return std::fabs(dot(column(1), column(1)) - lengthSquared) <= tolerance &&
         std::fabs(dot(column(2), column(2)) - lengthSquared) <= tolerance &&
         std::fabs(dot(column(0), column(1))) <= tolerance && std::fabs(dot(column(0), column(2))) <= tolerance &&
         std::fabs(dot(column(1), column(2))) <= tolerance;
}

bool PlaceStillShape(Shape& shape, const Affine& placement) {
  switch (shape.type) {
    case Shape::Type::kSphere:
      if (!IsUniform(placement)) return false;
      shape.center = placement.Apply(shape.center);
      shape.radius *= placement.MaxStretch();
      return true;
    case Shape::Type::kQuad:
      shape.corner = placement.Apply(shape.corner);
      shape.edgeU = placement.ApplyLinear(shape.edgeU);
      shape.edgeV = placement.ApplyLinear(shape.edgeV);
      return true;
    case Shape::Type::kMesh:
    case Shape::Type::kTerrain:
      // A still placement is built into world-space triangles of its own, as an inline
      // copy would be (see PlaceStillShapes in scene.h): its normals go to the world too.
      OwnMesh(shape);
      for (Vec3& v : shape.mesh.vertices) v = placement.Apply(v);
      double normalMatrix[3][3];
      placement.NormalMatrix(normalMatrix);
      for (Vec3& n : shape.mesh.normals) n = ApplyMatrix(normalMatrix, n);
      // Tangents are directions on the surface: they move as its edges do. A mirror turns
      // the bitangent over.
      for (auto& tangent : shape.mesh.tangents) {
        const Vec3 moved = placement.ApplyLinear({tangent[0], tangent[1], tangent[2]});
        tangent = {moved.x, moved.y, moved.z, placement.Determinant() < 0 ? -tangent[3] : tangent[3]};
      }
      // A mirror turns the triangles' winding over, and with it the face normals the
      // tracer takes from it: turned back, the outside stays outside (as glTF has it).
      if (placement.Determinant() < 0) {
        for (auto& triangle : shape.mesh.triangles) std::swap(triangle[1], triangle[2]);
      }
      return true;
  }
  return false;
}

}  // namespace

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
    if (PlaceStillShape(shape, shape.motion.WorldFromObject(scene.render.firstFrame))) shape.motion = Motion{};
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
