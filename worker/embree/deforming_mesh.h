// A mesh whose vertices move relative to one another (skins, morph targets: see
// scene/deformation.h), posed frame by frame.
//
// Each pose is a small Embree scene holding the mesh's one triangle geometry. Its tree is
// built once, from the rest pose, and afterwards only refit to each frame's vertices
// (RTC_BUILD_QUALITY_REFIT): the topology never depends on which frames a worker posed
// before, so a frame traces to the same bits on any worker, in any order.
//
// Poses are recycled: a pose no placed frame holds any more is refit to the next frame
// asked for. A frame whose pose equals one already made (its joints and morph weights
// unchanged, bit for bit) shares it and costs nothing.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <vector>

#include "worker/embree/device.h"
#include "worker/embree/surface_filter.h"
#include "proto/scene/scene.h"
#include "worker/shapes/shape_kind.h"

namespace tcfarm {

class DeformingMesh {
 public:
  // What a frame's vertices are made of: two frames with equal keys pose the same bits.
  using PoseKey = DeformationAt;
  // The shape's mesh at one frame: a committed scene to instance, and its normals.
  struct Pose {
    int frame = 0;
    std::shared_ptr<const PoseKey> key;
    SceneHandle scene;
    RTCGeometry geometry = nullptr;  // owned by `scene`
    std::shared_ptr<const SurfaceNormals> normals;
  };

  // Throws EmbreeError when Embree cannot build the rest pose.
  // filter: the shape's hit filters (surface_filter.h), which outlive this mesh.
  DeformingMesh(const EmbreeDevice& device, const Shape& shape, const SurfaceFilter* filter);

  // Thread-safe. The pose stays valid, and unchanged, while the caller holds it.
  std::shared_ptr<const Pose> AtFrame(int frame);

  // For the horizons of `exact`, thread-safe, each computed once per frame: the bounds of
  // each part's reach (DeformationParts) at a frame, and of each of its pieces, in the
  // mesh's object space (the world's for a skin); what the frame's pose is made of.
  struct PartBounds {
    std::vector<BoundingSphere> groups;               // by group
    std::vector<std::vector<BoundingSphere>> pieces;  // by group, by piece
  };
  std::shared_ptr<const PartBounds> PartBoundsAt(int frame);
  std::shared_ptr<const PoseKey> KeyOf(int frame);
  const DeformationParts& Parts() const { return parts_; }

  // Work counters: poses computed (vertices deformed and the tree refit), poses shared
  // because nothing changed, and vertices deformed in all.
  uint64_t PosesComputed() const;
  uint64_t PosesShared() const;
  uint64_t VerticesDeformed() const;

 private:
  std::shared_ptr<Pose> NewRestPose() const;
  void Refit(Pose& pose, int frame, std::shared_ptr<const PoseKey> key) const;
  template <typename Value, typename Compute>
  std::shared_ptr<const Value> Memo(std::map<int, std::shared_ptr<const Value>>& memo, int frame, Compute compute);

  const EmbreeDevice& device_;
  const Shape& shape_;
  const SurfaceFilter* filter_;

  mutable std::mutex mutex_;
  std::vector<std::shared_ptr<Pose>> poses_;  // every pose made; a use count of 1 means free
  DeformationParts parts_;
  std::map<int, std::shared_ptr<const PartBounds>> partBounds_;  // by frame
  std::map<int, std::shared_ptr<const PoseKey>> keys_;
  uint64_t posesComputed_ = 0, posesShared_ = 0, verticesDeformed_ = 0;
};

}  // namespace tcfarm
