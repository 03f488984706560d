#include "worker/embree/deforming_mesh.h"

#include "worker/embree/closest_hit.h"

namespace tcfarm {

DeformingMesh::DeformingMesh(const EmbreeDevice& device, const Shape& shape, const SurfaceFilter* filter)
    : device_(device), shape_(shape), filter_(filter),
      parts_(SplitIntoParts(shape.Mesh(), *shape.deformation)) {
  // The first pose is made now, so that a mesh Embree cannot build fails the scene at once.
  poses_.push_back(NewRestPose());
}

std::shared_ptr<DeformingMesh::Pose> DeformingMesh::NewRestPose() const {
  auto pose = std::make_shared<Pose>();
  RTCScene scene = rtcNewScene(device_.get());
  pose->scene = SceneHandle(scene);
  // A two-level, dynamic structure, so that the geometry's own tree is refit rather than
  // rebuilt (without the dynamic flag Embree rebuilds: 12 times slower on 51,200 triangles).
  rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_LOW);
  rtcSetSceneFlags(scene, RTCSceneFlags(RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_DYNAMIC));
  RTCGeometry geometry = KindOf(shape_).NewGeometry(device_.get(), shape_);  // the rest pose
  rtcSetGeometryBuildQuality(geometry, RTC_BUILD_QUALITY_REFIT);
  SetSurfaceFilters(geometry, filter_);
  rtcCommitGeometry(geometry);
  rtcAttachGeometry(scene, geometry);
  rtcReleaseGeometry(geometry);
  pose->geometry = geometry;
  rtcCommitScene(scene);
  device_.ThrowIfError("building a deforming mesh");
  pose->frame = -1;  // no frame's pose yet
  return pose;
}

void DeformingMesh::Refit(Pose& pose, int frame, std::shared_ptr<const PoseKey> key) const {
  const DeformedVertices deformed = Deform(shape_.Mesh(), *shape_.deformation, *key);
  auto* vertex = static_cast<float*>(rtcGetGeometryBufferData(pose.geometry, RTC_BUFFER_TYPE_VERTEX, 0));
  for (size_t i = 0; i < deformed.positions.size(); ++i) {
    for (int axis = 0; axis < 3; ++axis) vertex[3 * i + axis] = static_cast<float>(deformed.positions[i][axis]);
  }
  rtcUpdateGeometryBuffer(pose.geometry, RTC_BUFFER_TYPE_VERTEX, 0);
  rtcCommitGeometry(pose.geometry);
  rtcCommitScene(pose.scene.get());
  device_.ThrowIfError("refitting a deforming mesh");
  pose.normals = std::make_shared<const SurfaceNormals>(SurfaceNormals{
      TriangleFaceNormals(deformed.positions, shape_.Mesh().triangles), UnitVertexNormals(deformed.normals)});
  pose.frame = frame;
  pose.key = std::move(key);
}

std::shared_ptr<const DeformingMesh::Pose> DeformingMesh::AtFrame(int frame) {
  std::shared_ptr<const PoseKey> key = KeyOf(frame);
  std::lock_guard<std::mutex> lock(mutex_);
  // A pose with the same joint matrices and weights is this frame's pose already, held or
  // not: its vertices would be deformed to the same bits.
  for (const auto& pose : poses_) {
    if (pose->frame >= 0 && (pose->frame == frame || *pose->key == *key)) {
      ++posesShared_;
      return pose;
    }
  }
  std::shared_ptr<Pose> free;
  for (const auto& pose : poses_) {
    if (pose.use_count() == 1) {
      free = pose;
      break;
    }
  }
  if (!free) {
    free = NewRestPose();
    poses_.push_back(free);
  }
  // Refit under the lock: poses are few and a frame's tasks arrive together, so callers
  // would mostly wait for this very pose anyway.
  Refit(*free, frame, std::move(key));
  ++posesComputed_;
  verticesDeformed_ += shape_.Mesh().vertices.size();
  return free;
}

// A value computed once per frame and kept: looked up under the lock, computed outside it
// (two threads may both compute a frame; the first one stored wins, and both are equal).
template <typename Value, typename Compute>
std::shared_ptr<const Value> DeformingMesh::Memo(std::map<int, std::shared_ptr<const Value>>& memo, int frame,
                                                Compute compute) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    auto found = memo.find(frame);
    if (found != memo.end()) return found->second;
  }
  auto value = std::make_shared<const Value>(compute());
  std::lock_guard<std::mutex> lock(mutex_);
  return memo.emplace(frame, std::move(value)).first->second;
}

std::shared_ptr<const DeformingMesh::PartBounds> DeformingMesh::PartBoundsAt(int frame) {
  const std::shared_ptr<const PoseKey> key = KeyOf(frame);
  return Memo(partBounds_, frame, [&] {
    const std::vector<Vec3> positions = Deform(shape_.Mesh(), *shape_.deformation, *key, false).positions;
    std::vector<Vec3> points;
    auto boundsOf = [&](const std::vector<uint32_t>& vertices) {
      points.clear();
      for (uint32_t v : vertices) points.push_back(positions[v]);
      return BoundsOf(points);
    };
    PartBounds bounds;
    for (const DeformationParts::Group& group : parts_.groups) {
      bounds.groups.push_back(boundsOf(group.reach));
      std::vector<BoundingSphere>& pieces = bounds.pieces.emplace_back();
      for (const std::vector<uint32_t>& piece : group.pieces) pieces.push_back(boundsOf(piece));
    }
    return bounds;
  });
}

std::shared_ptr<const DeformingMesh::PoseKey> DeformingMesh::KeyOf(int frame) {
  return Memo(keys_, frame, [&] { return EvaluateDeformation(*shape_.deformation, frame); });
}

uint64_t DeformingMesh::PosesComputed() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return posesComputed_;
}

uint64_t DeformingMesh::PosesShared() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return posesShared_;
}

uint64_t DeformingMesh::VerticesDeformed() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return verticesDeformed_;
}

}  // namespace tcfarm
