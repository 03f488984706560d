// Validity horizons (the `exact` strategy): for a pixel traced at frame a, the first frame
// h > a at which something that changes could alter it. The pixel's ray tree at frame a
// (camera, shadow, reflection and refraction segments; a miss is a segment to infinity)
// is tested against conservative bounds of every moving shape at every frame a .. a+W:
// if no moving shape's bounds meet the ray tree at frame f, nothing the pixel sees has
// changed at f, so its value at f is bit-identical to its value at a (tracing is
// deterministic and the sample pattern is seeded by pixel).
//
// Bounds are spheres padded beyond the ray offsets. A segment "meets" a sphere when any
// of its points is inside, so a segment that starts inside counts too. Segments are
// tested from frame a+1 on: the trace at a found them clear of every shape (a segment
// ends at the first surface it meets, and a surface that moves caps the horizon at a+1
// by itself, unless it is a sphere's side no light reaches: UnlitSphereHolds), so the
// shapes' places at a cannot change the pixel. A camera that changes
// caps every horizon, and so does a light that changes, for every pixel that sees a
// surface.
//
// A shadow ray blocked at frame a is the exception (the tracer follows it, see
// tracer.cpp): a blocked light adds nothing, whoever blocks it, so the pixel keeps its
// value while the ray stays blocked. The tracer follows such a ray over the frames ahead,
// once the other rays have set the pixel's horizon: a frame where a moving sphere blocks
// it beyond doubt is settled by arithmetic (FirstNotSurelyBlocked), any other by its own
// Embree query, or, when only translating spheres move, taken as the frame it clears.
//
// The test is plain arithmetic over a few hundred proxies per task: measured several
// times faster than Embree queries with a filter callback over the same proxies, which
// must visit every proxy a segment crosses. Two searches share it:
// - FirstMeeting, segment by segment: culled by each shape's swept box and stopped at the
//   earliest frame found. For reflected and refracted rays, and any ray no fan takes.
// - FanFirstMeetings, frame by frame: camera rays leave one point (the eye) and shadow
//   rays toward a point or spot light end at one (the light), so each mover's bounds at
//   each frame find the few segments they may meet by direction (segment_fan.h), where
//   segment by segment most of the time went to culling paths that sweep the picture.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "proto/scene/scene.h"
#include "worker/embree/deforming_mesh.h"
#include "worker/shapes/shape_kind.h"
#include "worker/trace/float3.h"

namespace tcfarm {

class SegmentFan;
struct ShadingLight;

struct RaySegment {
  Float3 origin;
  Float3 direction;  // unit
  float length;      // infinity for a ray that escapes the scene
};

class HorizonOracle {
 public:
  // window: frames after `frame` to look at; horizons are capped at frame + window + 1,
  // meaning "valid through the whole window".
  // A deforming shape's posed meshes, by shape index: they know its bounds and its parts
  // at every frame. Rigid shapes' bounds are their rest pose's.
  using DeformingMeshes = std::function<DeformingMesh*(size_t shape)>;
  // walkFrames: how far ahead a blocked shadow ray may be followed (see WalkEnd); the
  // whole window by default.
  HorizonOracle(const Scene& scene, int frame, int window, const DeformingMeshes& deforming = {},
                int walkFrames = -1);

  int frame() const { return frame_; }
  int window() const { return window_; }
  int Unbounded() const { return frame_ + window_ + 1; }
  // The first frame a blocked shadow ray is not followed to: a pixel whose shadow ray is
  // followed gets a horizon no later than this. Following a ray asks the scene at every
  // frame ahead; a scene whose frames are dear to place (deforming meshes, posed per
  // frame) follows rays only over the frames its worker keeps placed.
  int WalkEnd() const { return walkEnd_; }
  // Cap for every pixel (the camera moves).
  int CameraCap() const { return cameraCap_; }
  // Cap for a pixel whose ray tree reaches a surface (a light changes).
  int LightCap() const { return lightCap_; }
  // The first frame after frame() and before `before` at which a moving shape's bounds
  // meet the segment, else `before` (at most Unbounded()). For segments the trace found
  // clear of every shape at frame(). A pixel's horizon is the least over its segments, so
  // each segment need only be searched up to the horizon the pixel has so far: frames
  // beyond it cannot lower it, and most of the search is skipped.
  // exceptMover: a mover left out of the search (-1: none).
  int FirstMeeting(const RaySegment& segment, int before, int exceptMover = -1) const;
  int FirstMeeting(const RaySegment& segment) const { return FirstMeeting(segment, Unbounded()); }
  // For a surface seen at frame(): the first frame after it at which the surface may
  // look different. A rigid shape that moves changes at frame() + 1; a deforming mesh
  // that only deforms changes when its triangle's corners are posed differently (the
  // parts of it that hold still stay still); a still shape never (Unbounded()).
  int SurfaceChange(int shape, uint32_t primitive) const;
  // The first moving shape whose bounds meet the segment at frame() itself (-1: none):
  // for a blocked shadow ray, what may block it. When none may, a still shape blocks it,
  // and keeps blocking it at every frame. The moving sphere a mover is (-1: none): the
  // likely blocker, the first one FirstNotSurelyBlocked tries.
  int MoverThatMayBlock(const RaySegment& segment, int exceptMover = -1) const;
  int SphereOfMover(int mover) const;
  // For a blocked shadow ray: the first frame in [from, before) at which no moving sphere
  // surely blocks it, else `before`. A sphere surely blocks a segment that runs through
  // it well inside, from outside to outside, with margins far above the rounding of the
  // tracer's own ray-sphere test, so that test says "blocked" too. Frame by frame, the
  // blocker found last (`hint`, kept across calls for one ray) is tried first: shadows
  // move slowly, the blocker rarely changes.
  int FirstNotSurelyBlocked(const RaySegment& segment, int from, int before, int* hint) const;
  // Whether every moving shape is a sphere that only translates, which FirstNotSurelyBlocked
  // settles by arithmetic. Then a blocked shadow ray no sphere surely blocks is taken to
  // clear there: the pixel is traced again, a few needlessly (the ray was still blocked,
  // by a still shape or at a sphere's rim), instead of asking Embree at every such frame,
  // which answered "clear" for 99 % of them on the paper's twelve spheres.
  bool OnlyTranslatingSpheresMove() const { return spheres_.size() == movers_.size(); }

  // A camera ray that meets a moving sphere no light reaches (every light is behind the
  // surface there, or blocked) shows the sphere's ambient colour, and keeps showing it
  // while the ray meets that sphere first, at a point no light reaches. Without this rule
  // a pixel on a sphere changes at every frame the sphere moves; on the paper's spheres
  // their unlit and shadowed sides were nearly all of exact's needless traces.
  // UnlitSphereHolds: the first frame in (frame(), before) at which that may stop
  // holding, else `before`: the ray, `hit` long at frame(), must meet the sphere from
  // outside, well inside its rim and well before `hit`; at the point it meets, each light
  // must be well behind the surface, or its shadow ray surely blocked (TestSureBlock's
  // margins) by the moving sphere `blockers[light]` (-1: none). Before `hit` the trace at
  // frame() found nothing still on the ray, so the sphere is met first wherever no other
  // mover's bounds meet the ray (the caller's FirstMeeting, leaving out the sphere's own
  // mover). Only spheres that merely translate (their centres are known to the tracer's
  // precision). Lights as at frame() (LightCap caps the horizon where they change).
  int SphereOfShape(int shape) const { return sphereOfShape_[static_cast<size_t>(shape)]; }
  int MoverOfSphere(int sphere) const { return static_cast<int>(spheres_[static_cast<size_t>(sphere)].mover); }
  int UnlitSphereHolds(int sphere, const RaySegment& hit, const std::vector<ShadingLight>& lights,
                       const int* blockers, int before) const;

  // FirstMeeting for many segments at once, frame by frame: the segments of a fan
  // (segment_fan.h), which share a point their lines pass through. For each frame ahead,
  // each mover's bounds visit only the segments whose directions fall in their cone from
  // that point, instead of each segment searching every mover's path. Lowers the
  // horizon of each segment's sample (horizon[entry.sample]) to its first meeting.
  // exceptMover, by sample where given: a mover left out of that sample's search (-1:
  // none), as FirstMeeting's.
  void FanFirstMeetings(const SegmentFan& fan, int32_t* horizon, const int32_t* exceptMover = nullptr) const;
  // A moving shape's bounds at frame() + offset (offset 0 .. window()), as the tests read
  // them; a negative radius where it has nothing that changed (it meets nothing).
  struct MoverSphere {
    float x, y, z, radius;
  };
  size_t MoverCount() const { return movers_.size(); }
  // Whether the segment meets the box of every mover's bounds over the window: where the
  // movers keep to a corner of the picture, most segments miss it and need no search (a
  // segment's test costs less than its place in a fan).
  bool NearAnyMover(const RaySegment& segment) const;
  MoverSphere MoverAt(size_t mover, size_t offset) const;
  // How far a fan's segments may pass from its point (SegmentFan::Add): far above the
  // tracer's ray offsets at the scale of the point and of the movers.
  double FanSlack(const Vec3& point) const;

 private:
  struct Box {
    Float3 lo, hi;
  };
  // Frames per chunk of a mover's path: a segment that misses a chunk's box skips its
  // frames' spheres, so a miss costs a few box tests instead of one test per frame.
  static constexpr size_t kFramesPerChunk = 8;
  struct Mover {
    float atFrame[4];             // its bounds at frame(), moving later or not: x, y, z, radius
    Box swept;                    // bounds of all its proxies over the window
    std::vector<Box> chunks;      // bounds of its proxies in frames [k * kFramesPerChunk, ...)
    // The chunks' boxes again, one array per coordinate, padded with empty boxes to a
    // multiple of kBoxLanes: a segment tests all of a near mover's chunks at once.
    std::vector<float> chunkLo[3], chunkHi[3];
    // Per frame a .. a+W, its proxy sphere: one array per coordinate and one of radii,
    // padded to whole chunks, so that a chunk's frames are tested in one SIMD loop.
    std::vector<float> x, y, z, radius;
    size_t frames = 0;            // proxies before the padding
    // Where the mover comes in pieces (a deforming mesh's part): per frame offset, its
    // pieces' proxies as four arrays of pieceLanes floats (x, y, z, radius; a negative
    // radius where a proxy is none, and in the padding), tested in one SIMD loop; and the
    // same at frame(). A segment meets the mover only where it meets its proxy and one of
    // its pieces: together they hold it as the proxy does, with less space around it.
    size_t pieceLanes = 0;
    std::vector<float> pieces, atFramePieces;
  };
  // A moving sphere as the tracer places it: per frame a .. a+W, its centre.
  struct MovingSphere {
    double radius;
    std::vector<Vec3> centers;
    double step = 0;  // the farthest its centre moves from one frame to the next
    size_t mover;     // its index in movers_
  };
  static Box EmptyBox();
  // For UnlitSphereHolds at one frame: whether the light adds nothing at p (on a sphere,
  // `outward` its normal radius long): well behind it, or its shadow ray from `start`
  // surely blocked by moving sphere `blocker`. A spot's cone and a light's range are not
  // asked: a light they leave out counts as seen, which only ends the horizon sooner.
  bool LightUnseen(const ShadingLight& light, const Vec3& p, const Vec3& outward, double slack, const Vec3& start,
                   int blocker, int frame) const;
  static uint32_t ChunkSpheresMet(const RaySegment& segment, const Mover& mover, size_t begin);
  // Whether the segment meets one of the mover's pieces at a frame offset (at frame()
  // itself for atFrame), where it has pieces; true where it has none.
  static bool PiecesMet(const RaySegment& segment, const Mover& mover, size_t offset);
  static bool PiecesMetAtFrame(const RaySegment& segment, const Mover& mover);
  static uint32_t LaneMask(size_t chunkBegin, size_t from, size_t to);
  // objectBounds(f): the shape's object-space bounds at frame f, a negative radius where
  // it has nothing that changed by f; atFrame: its bounds at frame() itself, where it may
  // block a shadow ray (MoverThatMayBlock), though objectBounds(frame()) is nothing.
  // objectPieces(f), where given: pieces of the same bounds (Mover::pieces), as many at
  // every frame, read at frame() and wherever objectBounds(f) is some.
  using PiecesAt = std::function<const std::vector<BoundingSphere>&(int frame)>;
  void AddMover(const Shape& shape, int lastFrame, const std::function<BoundingSphere(int frame)>& objectBounds,
                const BoundingSphere& atFrame, const PiecesAt& objectPieces = {});
  // A rigid shape: one mover, met nowhere at the frames it is placed as at frame().
  void AddRigidShape(const Shape& shape, size_t index, int lastFrame);
  // A deforming mesh: as one mover when it is placed as a whole too, else as one mover per
  // part (DeformationParts), each met only at the frames its part is posed otherwise
  // than at frame(); parts that hold still over the window are no mover at all.
  void AddDeformingMesh(const Shape& shape, size_t index, int lastFrame, DeformingMesh& mesh);
  // The first frame after frame() at which each shape, as a whole, may look different:
  // placed otherwise than at frame() (a pause in its motion is no change), else
  // Unbounded(). For a shape deforming in parts, Unbounded(): its triangles say.
  std::vector<int> wholeChange_;  // by shape
  // Per shape deforming in parts: its vertices' group and each group's first change.
  struct PartChanges {
    const DeformationParts* parts = nullptr;
    const TriangleMesh* mesh = nullptr;
    std::vector<int> groupChange;
  };
  std::vector<PartChanges> partChanges_;  // by shape, empty for the others

  int frame_, window_;
  int walkEnd_;
  int cameraCap_, lightCap_;
  std::vector<Mover> movers_;
  // The movers' swept boxes again, one array per coordinate, padded with empty boxes to
  // a multiple of kBoxLanes: every segment tests all of them, in a branch-free loop the
  // compiler turns into SIMD.
  static constexpr size_t kBoxLanes = 8;
  std::vector<float> sweptLo_[3], sweptHi_[3];
  static void LayBoxesOut(const std::vector<Box>& boxes, std::vector<float> (&lo)[3], std::vector<float> (&hi)[3]);
  std::vector<MovingSphere> spheres_;
  std::vector<int> sphereOfMover_;  // by mover: its index in spheres_, -1 for none
  std::vector<int> sphereOfShape_;  // by shape: its index in spheres_, -1 for none
  Box all_;  // bounds of every proxy: most segments miss it and cost one test
};

}  // namespace tcfarm
