#include "worker/embree/scene_geometry.h"

#include <algorithm>

#include "worker/embree/closest_hit.h"
#include "worker/embree/surface_filter.h"
#include "worker/embree/tie_candidates.h"
#include "worker/shapes/shape_kind.h"

namespace tcfarm {
namespace {

// Frames kept placed: a worker's in-flight tasks rarely span more frames than this, and
// an `exact` task re-tests blocked shadow rays on the frames ahead of its own. A placed
// frame is a top-level tree over one instance per moving shape: small, unless it holds
// deforming meshes, whose every frame is a posed copy of the mesh and its tree; then as
// many frames as the budget holds, and at least a few.
constexpr size_t kCachedFrames = 64;
// With deforming meshes each placed frame holds a pose, and a pose is made once by a full
// build of the rest pose and from then on refit: few frames kept means few builds (the
// first ones) and refits after, and the memory of a few copies of the mesh. Keeping a
// whole window placed for `exact`'s walks over blocked shadow rays (48 frames of a
// 50,000-triangle character, 6 MB each) cost more in builds than the walks saved: its
// job's wall went from 0.46 of brute force's to 0.57.
constexpr size_t kDeformingCachedFrames = 12;
constexpr size_t kMinCachedFrames = 4;
constexpr double kPoseBudgetBytes = 512.0 * 1024 * 1024;
constexpr double kPoseBytesPerTriangle = 120;  // Embree's tree (~100) and the vertices

size_t FramesToCache(const Scene& scene) {
  double deformingTriangles = 0;
  for (const Shape& shape : scene.shapes) {
    if (shape.Deforms()) deformingTriangles += static_cast<double>(shape.Mesh().triangles.size());
  }
  if (deformingTriangles == 0) return kCachedFrames;
  const double fits = kPoseBudgetBytes / (deformingTriangles * kPoseBytesPerTriangle);
  return static_cast<size_t>(std::clamp(fits, double(kMinCachedFrames), double(kDeformingCachedFrames)));
}

// Attaches the shape to `scene` and returns its geometry id. Only a scene whose surfaces may
// tie over an area pays for the tie rule (tie_candidates.h).
unsigned AttachShape(RTCDevice device, RTCScene scene, const Shape& shape, const SurfaceFilter* filter) {
  RTCGeometry geometry = KindOf(shape).NewGeometry(device, shape);
  SetSurfaceFilters(geometry, filter);
  rtcCommitGeometry(geometry);
  unsigned id = rtcAttachGeometry(scene, geometry);
  rtcReleaseGeometry(geometry);
  return id;
}

// Embree asks while it builds a tree: returning false cancels the build.
bool KeepBuilding(void* stop, double /*progress*/) { return !StopRequested(static_cast<BuildStop>(stop)); }

RTCScene NewStaticScene(RTCDevice device, bool robust) {
  RTCScene scene = rtcNewScene(device);
  if (robust) rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
  return scene;
}

unsigned AttachInstance(RTCDevice device, RTCScene top, RTCScene child, const Affine& placement) {
  RTCGeometry instance = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_INSTANCE);
  rtcSetGeometryInstancedScene(instance, child);
  // Column-major 3x4: the linear part's columns, then the translation column. Computed in
  // double and rounded once, so a translation alone places exactly as it always did.
  float worldFromObject[12];
  for (int column = 0; column < 3; ++column) {
    for (int row = 0; row < 3; ++row) worldFromObject[3 * column + row] = static_cast<float>(placement.linear[row][column]);
  }
  worldFromObject[9] = static_cast<float>(placement.offset.x);
  worldFromObject[10] = static_cast<float>(placement.offset.y);
  worldFromObject[11] = static_cast<float>(placement.offset.z);
  rtcSetGeometryTransform(instance, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, worldFromObject);
  rtcCommitGeometry(instance);
  unsigned id = rtcAttachGeometry(top, instance);
  rtcReleaseGeometry(instance);
  return id;
}

}  // namespace

bool HasSharedEdges(const Shape& shape) { return KindOf(shape).SharesEdges(); }

bool NeedsRobustTraversal(const Scene& scene) {
  return std::any_of(scene.shapes.begin(), scene.shapes.end(), HasSharedEdges);
}

void FrameGeometry::SetNormalTransform(int shape, const Affine& worldFromObject) {
  if (normalFromObject_.size() <= static_cast<size_t>(shape)) normalFromObject_.resize(shape + 1);
  NormalTransform& out = normalFromObject_[shape];
  out.present = true;
  worldFromObject.NormalMatrix(out.matrix);
  Cofactor(worldFromObject.linear, out.cofactor);
}

Vec3 FrameGeometry::NormalToWorld(int shape, const Vec3& objectNormal) const {
  if (static_cast<size_t>(shape) >= normalFromObject_.size() || !normalFromObject_[shape].present) {
    return objectNormal;
  }
  return ApplyMatrix(normalFromObject_[shape].matrix, objectNormal);
}

Vec3 FrameGeometry::AreaToWorld(int shape, const Vec3& objectCross) const {
  if (!HasNormalTransform(shape)) return objectCross;
  return ApplyMatrix(normalFromObject_[shape].cofactor, objectCross);
}

SceneGeometry::SceneGeometry(const EmbreeDevice& device, const Scene& scene, BuildStop stop,
                             const std::vector<const SurfaceRule*>& rules)
    : device_(device), scene_(scene), robust_(NeedsRobustTraversal(scene)),
      staticScene_(NewStaticScene(device.get(), robust_)),
      settlesTies_(SceneMayTie(scene)),
      normals_(PerShapeOncePerMesh<SurfaceNormals>(scene.shapes, [stop](const Shape& shape) {
        ThrowIfStopRequested(stop);
        return SurfaceNormals{KindOf(shape).FaceNormals(shape), KindOf(shape).VertexNormals(shape)};
      })),
      cachedFrames_(FramesToCache(scene)) {
  for (size_t i = 0; i < scene.shapes.size(); ++i) {
    filters_.push_back(std::make_unique<SurfaceFilter>(SurfaceFilter{i < rules.size() ? rules[i] : nullptr, settlesTies_}));
  }
  for (size_t i = 0; i < scene.shapes.size(); ++i) {
    ThrowIfStopRequested(stop);
    const Shape& shape = scene.shapes[i];
    // A shape whose motion is not the identity is placed by an instance: at each frame
    // when it moves, or held at one place when it never does (PrepareForTracing builds
    // the latter in place where it can, sparing the per-frame placement).
    if (shape.Deforms()) {
      movers_.push_back({static_cast<int>(i), SceneHandle(), std::make_unique<DeformingMesh>(device, shape, filters_[i].get())});
      deformingOfShape_.resize(scene.shapes.size(), nullptr);
      deformingOfShape_[i] = movers_.back().deforming.get();
    } else if (!shape.motion.IsNone()) {
      movers_.push_back({static_cast<int>(i), ObjectScene(shape), nullptr});
    } else {
      unsigned id = AttachShape(device.get(), staticScene_.get(), shape, filters_[i].get());
      if (staticShapeOfGeometry_.size() <= id) staticShapeOfGeometry_.resize(id + 1, -1);
      staticShapeOfGeometry_[id] = static_cast<int>(i);
      hasStaticShapes_ = true;
    }
  }
  if (stop) rtcSetSceneProgressMonitorFunction(staticScene_.get(), KeepBuilding, const_cast<std::atomic<bool>*>(stop));
  rtcCommitScene(staticScene_.get());
  rtcSetSceneProgressMonitorFunction(staticScene_.get(), nullptr, nullptr);
  if (StopRequested(stop)) {
    rtcGetDeviceError(device.get());  // the cancelled build's error, which is this stop
    throw BuildStopped();
  }
  device.ThrowIfError("building the scene's geometry");
  if (movers_.empty()) {
    staticFrame_ = std::make_shared<FrameGeometry>();
    rtcRetainScene(staticScene_.get());
    staticFrame_->top_ = SceneHandle(staticScene_.get());
    staticFrame_->staticShapeOfGeometry_ = &staticShapeOfGeometry_;
    staticFrame_->settlesTies_ = settlesTies_;
    staticFrame_->normals_ = normals_;
  }
}

SceneHandle SceneGeometry::ObjectScene(const Shape& shape) {
  // A shape with a rule of its own (an alpha mask, culling) keeps its own tree: the rule
  // is the geometry's, and placements may have other materials.
  if (!shape.SharesMesh() || FilterOf(shape).rule) return NewObjectScene(shape);
  // One tree per shared mesh, whichever shape placed it first: its geometry and tie rule
  // are those of every placement (the rule keys hits by instance, i.e. by shape).
  auto [entry, isNew] = sharedMeshScenes_.try_emplace(shape.sharedMesh.get());
  if (isNew) entry->second = NewObjectScene(shape);
  rtcRetainScene(entry->second.get());
  return SceneHandle(entry->second.get());
}

SceneHandle SceneGeometry::NewObjectScene(const Shape& shape) const {
  SceneHandle scene(NewStaticScene(device_.get(), HasSharedEdges(shape)));
  AttachShape(device_.get(), scene.get(), shape, &FilterOf(shape));
  rtcCommitScene(scene.get());
  return scene;
}

std::shared_ptr<FrameGeometry> SceneGeometry::BuildFrame(int frame) const {
  auto placed = std::make_shared<FrameGeometry>();
  RTCScene top = rtcNewScene(device_.get());
  // A handful of instances: a fast build beats a good tree.
  rtcSetSceneBuildQuality(top, RTC_BUILD_QUALITY_LOW);
  if (robust_) rtcSetSceneFlags(top, RTC_SCENE_FLAG_ROBUST);
  placed->top_ = SceneHandle(top);
  placed->staticShapeOfGeometry_ = &staticShapeOfGeometry_;
  placed->settlesTies_ = settlesTies_;
  placed->normals_ = normals_;
  auto recordInstance = [&](unsigned id, int shape) {
    if (placed->shapeOfInstance_.size() <= id) placed->shapeOfInstance_.resize(id + 1, -1);
    placed->shapeOfInstance_[id] = shape;
  };
  if (hasStaticShapes_) {
    recordInstance(AttachInstance(device_.get(), top, staticScene_.get(), Affine{}), -1);
  }
  for (const Mover& mover : movers_) {
    const Motion& motion = scene_.shapes[mover.shape].motion;
    const Affine worldFromObject = motion.WorldFromObject(frame);
    RTCScene object = mover.scene.get();
    if (mover.deforming) {
      std::shared_ptr<const DeformingMesh::Pose> pose = mover.deforming->AtFrame(frame);
      object = pose->scene.get();
      placed->normals_[static_cast<size_t>(mover.shape)] = pose->normals;
      placed->poses_.push_back(std::move(pose));
    }
    recordInstance(AttachInstance(device_.get(), top, object, worldFromObject), mover.shape);
    if (!motion.IsTranslationOnly()) placed->SetNormalTransform(mover.shape, worldFromObject);
  }
  rtcCommitScene(top);
  device_.ThrowIfError("placing a frame's moving shapes");
  return placed;
}

std::shared_ptr<const FrameGeometry> SceneGeometry::ForFrame(int frame) {
  if (staticFrame_) return staticFrame_;
  std::lock_guard<std::mutex> lock(cacheMutex_);
  for (auto it = recentFrames_.begin(); it != recentFrames_.end(); ++it) {
    if (it->first == frame) {
      recentFrames_.splice(recentFrames_.begin(), recentFrames_, it);
      return it->second;
    }
  }
  recentFrames_.emplace_front(frame, BuildFrame(frame));
  ++frameBuilds_;
  if (recentFrames_.size() > cachedFrames_) recentFrames_.pop_back();
  return recentFrames_.front().second;
}

bool SceneGeometry::HasDeformingMeshes() const { return !deformingOfShape_.empty(); }

size_t SceneGeometry::CachedFrames() const { return cachedFrames_; }

DeformingMesh* SceneGeometry::Deforming(size_t shape) const {
  return shape < deformingOfShape_.size() ? deformingOfShape_[shape] : nullptr;
}

SceneGeometry::DeformationWork SceneGeometry::DeformationCounts() const {
  DeformationWork work;
  for (const Mover& mover : movers_) {
    if (!mover.deforming) continue;
    work.posesComputed += mover.deforming->PosesComputed();
    work.posesShared += mover.deforming->PosesShared();
    work.verticesDeformed += mover.deforming->VerticesDeformed();
  }
  return work;
}

uint64_t SceneGeometry::FrameBuilds() const {
  std::lock_guard<std::mutex> lock(cacheMutex_);
  return frameBuilds_;
}

const SurfaceFilter& SceneGeometry::FilterOf(const Shape& shape) const {
  return *filters_[static_cast<size_t>(&shape - scene_.shapes.data())];
}

}  // namespace tcfarm
