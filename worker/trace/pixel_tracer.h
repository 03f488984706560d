// The tracer's inside, shared by its source files: what shading reads of each shape at a
// frame, the frame's context, and one thread's PixelTracer. tracer.cpp traces (camera
// packets, secondary rays, shadow rays and their horizons) and asks each hit's material
// model (materials.h) for its shading; a model's files (worker/trace/materials/) take the
// PixelTracer for what they ask of the hit and the rays they spawn. Not part of the
// library's face (worker/tracing.h).
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include "worker/embree/closest_hit.h"
#include "worker/embree/ray_packets.h"
#include "worker/trace/camera.h"
#include "worker/trace/float3.h"
#include "worker/trace/horizon_tracker.h"
#include "worker/trace/horizons.h"
#include "worker/trace/lights.h"
#include "worker/trace/materials.h"
#include "worker/trace/ray_cone.h"
#include "worker/trace/ray_offset.h"
#include "worker/trace/tracer.h"

namespace tcfarm {
namespace tracing_detail {

constexpr float kInfinity = std::numeric_limits<float>::infinity();
inline bool IsZero(const Float3& v) { return v.x == 0 && v.y == 0 && v.z == 0; }

}  // namespace tracing_detail

using tracing_detail::IsZero;
using tracing_detail::kInfinity;

// What shading reads of a shape at a frame, gathered once per task: a hit reads one small
// record instead of following the scene, the frame's geometry and the per-shape tables.
struct Tracer::ShapeShading {
  const Float3* faceNormals = nullptr;    // unit, by triangle; null: Embree's normal
  const Float3* vertexNormals = nullptr;  // by vertex; null: flat
  const std::array<uint32_t, 3>* triangles = nullptr;
  const Float3* colors = nullptr;  // linear RGB by vertex, multiplying the diffuse; null: none
  // Texture coordinates (TEXCOORD_0, _1) and tangents, where the material reads them and
  // the mesh has them; else null.
  const std::array<float, 2>* uvs = nullptr;
  const std::array<float, 2>* uvs1 = nullptr;
  const std::array<float, 4>* tangents = nullptr;
  bool VariesDiffuse() const { return uvs || colors; }
  bool turns = false;  // its normals need carrying to the world (FrameGeometry::NormalToWorld)
  int material = 0;
};

struct Tracer::FrameContext {
  int frame;
  std::shared_ptr<const FrameGeometry> geometry;
  SceneGeometry* frames;  // places later frames, for shadow rays re-tested there
  PerspectiveCamera camera;
  std::vector<ShadingLight> lights;
  const std::vector<ShadingMaterial>* materials;
  std::vector<ShapeShading> shapes;  // by shape
  Float3 background;
  int maxDepth;
  int samplesPerPixel;
  bool anySecondary;  // some material reflects or refracts
  bool shadows;       // shadow rays traced (RenderSettings::shadows)
  bool anyBlend;      // some material blends (alphaMode BLEND): shadow rays weigh it
  float ambient;      // RenderSettings::ambient
};

// One thread's view of a frame: shades hits, casts secondary rays, counts rays.
class Tracer::PixelTracer {
 public:
  // Camera rays of neighbouring pixels, and their shadow rays toward one light, travel
  // together as packets, but in Embree's incoherent mode (the context's default): its
  // coherent mode culls by the packet's common frustum, which far from the origin (1e4
  // and beyond) lost rays that straddle the view's axis, so a pixel's bits depended on
  // its packet mates. Ties between coplanar surfaces are settled by the context's rule.
  PixelTracer(const FrameContext& frame, const Scene& scene)
      : frame_(frame), scene_(scene), context_(frame.geometry.get()) {}

  // Traces `count` (<= Width, the packet's: ray_packets.h) camera samples and writes their
  // colours.
  template <int Width>
  void TracePrimaryPacket(const uint32_t* pixel, const int* sample, int count, Float3* color);
  // A secondary ray, its cone `coneWidth` wide at `origin` (ray_cone.h).
  Float3 TraceRay(Float3 origin, Float3 direction, int depth, float coneWidth);
  const RayCounts& counts() const { return counts_; }
  // Folds every ray of the packets traced from now on into their horizons.
  void TrackHorizons(HorizonTracker* tracker) { horizons_ = tracker; }
  // Follows the blocked shadow rays of the samples traced so far, frame by frame ahead,
  // while they stay blocked and below their sample's horizon: a blocked light adds
  // nothing, whoever blocks it. The horizon becomes the first frame one clears at.
  template <int Width>
  void FollowBlockedShadowRays(int32_t* sampleHorizon);

  using ShapeShading = Tracer::ShapeShading;
  struct SurfaceHit {
    Float3 position;
    Float3 normal;     // unit shading normal, on the side the ray arrived from
    Float3 faceNormal;  // unit, of the surface itself, on that side: offsets go along it
    Float3 direction;  // unit direction of the arriving ray
    bool fromInside;   // arrived against the geometric normal (leaving a solid)
    bool unlit;        // its material shows itself whatever lights it (no shadow rays)
    float offset;      // distance that clears the hit point's rounding error
    int shape;
    uint32_t primitive;  // of a mesh: the triangle hit
    int material;
    MaterialSurface surface;  // what its material's model reads of it here (its Shade)
    // The pixel's ray cone's width here: it filters glTF textures, and the secondary rays
    // leaving the hit start with it (spreading on as the camera's; surfaces' curvature
    // is not followed). 0 for shadow rays' hits: their textures are read at full size.
    float coneWidth;
  };

  // The Embree hit fields a surface hit is made from.
  struct RawHit {
    float t;
    Float3 geometricNormal;
    unsigned instanceId, geometryId, primitiveId;
    float u, v;  // barycentric coordinates of the hit in its triangle
  };
  // For the material models (materials.h): a secondary ray leaving the hit (reflected, or
  // transmitted through the surface) along unit `direction`, counted, and the colour it
  // brings back; and what their shading reads of the frame.
  Float3 Secondary(const SurfaceHit& hit, bool transmitted, Float3 direction, int depth) {
    ++(transmitted ? counts_.refraction : counts_.reflection);
    return TraceRay(Spawn(hit, transmitted), direction, depth + 1, hit.coneWidth);
  }
  const Scene& scene() const { return scene_; }
  const FrameGeometry& geometry() const { return *frame_.geometry; }
  // A normal carried to the world and made unit (kept as it is when already unit and the
  // shape does not turn); zero stays zero. Inline for the common shape that does not turn.
  Float3 ToWorld(int shape, bool turns, const Float3& normal, bool unit = false) const {
    if (turns) return TurnedToWorld(shape, normal);
    if (unit) return normal;  // computed unit in double: kept to the bit
    float length = Length(normal);
    return (length > 0 && std::isfinite(length)) ? normal * (1.0f / length) : Float3{};
  }

 private:
  // The closest hit along a ray within `farthest`, by the tie rule; none when it meets nothing.
  std::optional<RawHit> ClosestHit(Float3 origin, Float3 direction, float farthest);
  // The normal a smooth mesh shades this hit with, in object space; zero when flat.
  static Float3 SmoothNormal(const ShapeShading& shape, const RawHit& raw);
  Float3 TurnedToWorld(int shape, const Float3& normal) const;
  // Vectors by reference: passed by value, their packed halves went through the stack
  // and stalled every hit on the store forwarding.
  SurfaceHit MakeHit(const Float3& origin, const Float3& direction, const RawHit& raw, float coneWidth) const;
  // Light arriving at the hit from light i if nothing blocks it; false when the light is
  // behind the surface, or the surface is unlit (then no shadow ray is needed at all).
  // Inline, as LightContribution and Ambient: asked for every hit and light, Phong's
  // shading costs more as a call than as work (glTF's model's parts are calls of their own).
  bool ShadowRay(const SurfaceHit& hit, size_t light, Float3* direction, float* distance) const {
    if (hit.unlit) return false;
    return frame_.lights[light].Toward(hit.position, hit.normal, direction, distance);
  }
  // Inline: asked for every lit hit and light.
  Float3 LightContribution(const SurfaceHit& hit, size_t light, Float3 direction, float distance) const {
    const ShadingLight& l = frame_.lights[light];
    const Float3 color = WithModel(MaterialOf(hit), [&](const auto& m) {
      return m.Reflected(SurfaceOf(m, hit.surface), direction, hit.normal, hit.direction);
    });
    return color * l.intensity * l.Arriving(direction, distance);
  }
  // What the surface shows with no light: the ambient term, and its own emission.
  Float3 Ambient(const SurfaceHit& hit) const {
    return WithModel(MaterialOf(hit), [&](const auto& m) {
      return m.Ambient(SurfaceOf(m, hit.surface), hit.direction, frame_.ambient);
    });
  }
  const ShadingMaterial& MaterialOf(const SurfaceHit& hit) const { return (*frame_.materials)[hit.material]; }
  // The hit's local light with the rays its material spawns (mirror, refraction), below
  // the depth limit.
  Float3 Combine(const SurfaceHit& hit, Float3 local, int depth);
  // The share of a light that passes the blended surfaces between an unblocked shadow ray's
  // start and the light: 1 - alpha of each, met front to back (closest hit after closest
  // hit: the order, and so the rounding, is the ray's own).
  float BlendTransmittance(Float3 start, Float3 direction, float distance);
  void NoteSurface(int lane, const SurfaceHit& hit);
  // For a camera sample whose hit no light reaches, once its packet's lights are done:
  // when the hit is on a moving sphere (whose surface alone set the horizon to the next
  // frame), the horizon by HorizonOracle::UnlitSphereHolds instead, and the camera
  // segment's search for the other movers.
  void SettleUnlitMovingSphere(int lane, const SurfaceHit& hit, const RaySegment& eye);
  // Folds a packet's shadow rays toward one light into their samples' horizons.
  template <int Width>
  void ShadowHorizons(size_t light, const typename RayPacket<Width>::Ray& query, const int* valid,
                      const int* blocked);
  // A shadow ray found blocked, as it was asked, to be followed over the frames ahead.
  struct BlockedShadowRay {
    uint32_t sample;  // in the chunk
    int blocker;      // the moving sphere that likely blocks it, -1: not known
    RTCRay ray;
  };
  std::vector<BlockedShadowRay> walks_;
  std::vector<int> blockers_;  // by light, for SettleUnlitMovingSphere
  Float3 Spawn(const SurfaceHit& hit, bool transmitted) const {
    return hit.position + hit.faceNormal * (transmitted ? -hit.offset : hit.offset);
  }
  // The traceable scene of a frame after this one, placed once per chunk of pixels.
  RTCScene SceneAhead(int frame);

  const FrameContext& frame_;
  const Scene& scene_;
  ClosestHitContext context_;
  RayCounts counts_;
  HorizonTracker* horizons_ = nullptr;
  std::vector<std::shared_ptr<const FrameGeometry>> framesAhead_;  // [f - frame - 1]
};

}  // namespace tcfarm
