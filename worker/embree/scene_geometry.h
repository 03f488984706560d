// The Embree side of a scene: geometry built once, placed per frame.
//
// Shapes that never move go into one static scene, built once with a high-quality BVH.
// Each moving shape gets its own small scene, instanced into a per-frame top level with
// its transform (translation, rotation, scale) at that frame; moving shapes placing one
// shared mesh (Scene::meshes) instance one scene between them. A still placement of a
// shared mesh is built in place (PlaceStillShapes) like any still shape: an instance
// would trace other bits than the same mesh written inline. A deforming mesh (skin, morph
// targets) is posed per frame by a DeformingMesh and instanced like any mover. When
// nothing moves, every frame shares the static scene and no per-frame work happens at all
// (FrameBuilds() stays 0).
#pragma once

#include <cstdint>
#include <list>
#include <map>
#include <memory>
#include <mutex>
#include <vector>

#include "worker/embree/deforming_mesh.h"
#include "worker/embree/device.h"
#include "worker/embree/surface_filter.h"
#include "proto/scene/scene.h"
#include "worker/util/build_stop.h"

namespace tcfarm {

// Robust traversal (RTC_SCENE_FLAG_ROBUST, Embree's watertight triangle test) keeps rays
// from slipping through the edge two triangles share: a mesh's, or a quad's diagonal. A
// shape without such edges (ShapeKind::SharesEdges: a sphere) gets its own tree without
// the robust kernels.
bool HasSharedEdges(const Shape& shape);
// Whether any shape has shared edges: the still shapes' tree and each frame's top level
// are then traversed robustly.
bool NeedsRobustTraversal(const Scene& scene);

// The traceable geometry of one frame.
class FrameGeometry {
 public:
  RTCScene scene() const { return top_.get(); }
  // The scene's shape index for a hit's (instID[0], geomID).
  // Inline, as HasNormalTransform: asked for every hit.
  int ShapeOf(unsigned instanceId, unsigned geometryId) const {
    if (instanceId == RTC_INVALID_GEOMETRY_ID) return (*staticShapeOfGeometry_)[geometryId];
    int shape = shapeOfInstance_[instanceId];
    return shape >= 0 ? shape : (*staticShapeOfGeometry_)[geometryId];
  }
  // Whether the scene's shapes carry the tie rule (embree/tie_candidates.h).
  bool SettlesTies() const { return settlesTies_; }
  // Embree reports an instanced shape's normals in its object space: a shape that turns
  // or scales needs them carried to the world (not normalised). Still and merely
  // translated shapes return the normal as it is.
  bool HasNormalTransform(int shape) const {
    return static_cast<size_t>(shape) < normalFromObject_.size() && normalFromObject_[shape].present;
  }
  Vec3 NormalToWorld(int shape, const Vec3& objectNormal) const;
  // An object-space cross product of two edges (twice a triangle's area, along its normal)
  // carried to the world: its length there is twice the placed triangle's area. As it is
  // where the shape has no normal transform (still, or merely translated).
  Vec3 AreaToWorld(int shape, const Vec3& objectCross) const;
  // The shape's normals at this frame (SurfaceNormals), in its object space.
  const SurfaceNormals& Normals(int shape) const { return *normals_[static_cast<size_t>(shape)]; }

 private:
  friend class SceneGeometry;
  struct NormalTransform {
    bool present = false;
    double matrix[3][3];
    double cofactor[3][3];  // of the linear part: carries cross products (AreaToWorld)
  };
  void SetNormalTransform(int shape, const Affine& worldFromObject);
  std::vector<NormalTransform> normalFromObject_;  // by shape
  SceneHandle top_;
  const std::vector<int>* staticShapeOfGeometry_ = nullptr;
  bool settlesTies_ = false;
  std::vector<int> shapeOfInstance_;  // -1: the instance of the static scene
  std::vector<std::shared_ptr<const SurfaceNormals>> normals_;  // by shape
  std::vector<std::shared_ptr<const DeformingMesh::Pose>> poses_;  // held while the frame lives
};

class SceneGeometry {
 public:
  // Throws BuildStopped once `stop` is set (util/build_stop.h).
  // rules: by shape, which of its hits count (surface_filter.h; null or missing: all);
  // they outlive the geometry.
  SceneGeometry(const EmbreeDevice& device, const Scene& scene, BuildStop stop = nullptr,
                const std::vector<const SurfaceRule*>& rules = {});

  // Thread-safe. The last few frames are cached: tasks of one frame arrive together.
  std::shared_ptr<const FrameGeometry> ForFrame(int frame);
  bool HasDeformingMeshes() const;
  // How many placed frames ForFrame keeps, the last ones asked for.
  size_t CachedFrames() const;
  // Top-level scenes built for individual frames (0 when nothing moves).
  uint64_t FrameBuilds() const;
  // Deforming meshes' work: poses computed and vertices deformed (0 without deformation),
  // poses shared by frames whose joints and weights did not change.
  struct DeformationWork {
    uint64_t posesComputed = 0, posesShared = 0, verticesDeformed = 0;
  };
  DeformationWork DeformationCounts() const;
  // A deforming shape's posed meshes (null for any other shape): for the horizons.
  DeformingMesh* Deforming(size_t shape) const;

 private:
  struct Mover {
    int shape;
    SceneHandle scene;                        // a rigid mover's rest pose
    std::unique_ptr<DeformingMesh> deforming;  // or a deforming mesh's poses
  };
  std::shared_ptr<FrameGeometry> BuildFrame(int frame) const;
  // The shape in its rest pose, as a scene of its own to instance: shapes placing one
  // shared mesh get one scene between them.
  SceneHandle ObjectScene(const Shape& shape);
  SceneHandle NewObjectScene(const Shape& shape) const;
  const SurfaceFilter& FilterOf(const Shape& shape) const;

  const EmbreeDevice& device_;
  const Scene& scene_;
  const bool robust_;  // NeedsRobustTraversal(scene_)
  SceneHandle staticScene_;
  bool hasStaticShapes_ = false;
  std::vector<int> staticShapeOfGeometry_;
  bool settlesTies_ = false;
  std::vector<Mover> movers_;
  std::vector<DeformingMesh*> deformingOfShape_;  // by shape (movers_' own); empty without any
  std::map<const TriangleMesh*, SceneHandle> sharedMeshScenes_;
  std::vector<std::unique_ptr<SurfaceFilter>> filters_;  // by shape; its geometries point at them
  std::shared_ptr<FrameGeometry> staticFrame_;  // used for every frame when nothing moves
  // Per shape, its normals as the scene gives them; shapes placing one shared mesh share
  // them. A deforming mesh's are replaced per frame by its pose's.
  std::vector<std::shared_ptr<const SurfaceNormals>> normals_;
  size_t cachedFrames_;

  mutable std::mutex cacheMutex_;
  std::list<std::pair<int, std::shared_ptr<FrameGeometry>>> recentFrames_;
  uint64_t frameBuilds_ = 0;
};

}  // namespace tcfarm
