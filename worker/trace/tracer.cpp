#include "worker/trace/tracer.h"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "worker/embree/closest_hit.h"
#include "worker/embree/ray_packets.h"
#include "worker/shapes/shape_kind.h"
#include "worker/trace/camera.h"
#include "worker/trace/float3.h"
#include "worker/trace/horizon_tracker.h"
#include "worker/trace/horizons.h"
#include "worker/trace/segment_fan.h"
#include "worker/trace/lights.h"
#include "worker/trace/materials.h"
#include "worker/trace/materials/gltf_surface_rule.h"
#include "worker/trace/ray_offset.h"

namespace tcfarm {
namespace {

// Pixels handed to a thread at a time: at least enough to fill 16-wide packets many times,
// and about kChunksPerThread chunks a thread, so that threads stay balanced while the
// fixed cost of a chunk (its thread's CPU clock, read twice through a system call, and
// its tracer) stays small against a large task's tracing.
// With horizons a chunk also searches its fans once per mover and span of frames ahead,
// whatever its size: fewer, larger chunks.
constexpr size_t kMinPixelsPerChunk = 128;
constexpr size_t kChunksPerThread = 16;
constexpr size_t kChunksPerThreadWithHorizons = 4;

size_t PixelsPerChunk(size_t pixelCount, unsigned threads, bool horizons) {
  const size_t chunksPerThread = horizons ? kChunksPerThreadWithHorizons : kChunksPerThread;
  return std::max(kMinPixelsPerChunk, pixelCount / (size_t{threads} * chunksPerThread));
}
constexpr float kInfinity = std::numeric_limits<float>::infinity();

// A frame holds finite values only. Light beyond float range (a huge intensity at a tiny
// distance) saturates to the largest float rather than going black; NaN, which no scene
// should produce, becomes 0.
float StorableChannel(float value) {
  if (std::isnan(value)) return 0.0f;
  return std::clamp(value, -std::numeric_limits<float>::max(), std::numeric_limits<float>::max());
}

bool IsZero(const Float3& v) { return v.x == 0 && v.y == 0 && v.z == 0; }

std::vector<const SurfaceRule*> RulesOf(const std::vector<std::unique_ptr<SurfaceRule>>& rules) {
  std::vector<const SurfaceRule*> pointers;
  for (const auto& rule : rules) pointers.push_back(rule.get());
  return pointers;
}

bool AnyMaterialBlends(const Scene& scene) {
  return std::any_of(scene.materials.begin(), scene.materials.end(), [](const Material& m) {
    return m.pbr && m.pbr->alphaMode == MetallicRoughness::Alpha::kBlend;
  });
}

uint64_t ThreadCpuNanoseconds() {
  timespec now{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
  return static_cast<uint64_t>(now.tv_sec) * 1000000000u + static_cast<uint64_t>(now.tv_nsec);
}

}  // namespace

// What shading reads of a shape at a frame, gathered once per task: a hit reads one small
// record instead of following the scene, the frame's geometry and the per-shape tables.
struct Tracer::ShapeShading {
  const Float3* faceNormals = nullptr;    // unit, by triangle; null: Embree's normal
  const Float3* vertexNormals = nullptr;  // by vertex; null: flat
  const std::array<uint32_t, 3>* triangles = nullptr;
  const std::array<float, 2>* uvs = nullptr;  // null unless the shape is textured and has them
  const TextureImage* texture = nullptr;
  const Float3* colors = nullptr;  // linear RGB by vertex, multiplying the diffuse; null: none
  // glTF materials: the second texture coordinates and the tangents, where the material
  // reads them and the mesh has them.
  const std::array<float, 2>* uvs1 = nullptr;
  const std::array<float, 4>* tangents = nullptr;
  const PbrMaterial* pbr = nullptr;  // the shape's material, when it is glTF's
  bool VariesDiffuse() const { return uvs || colors; }
  bool turns = false;  // its normals need carrying to the world (FrameGeometry::NormalToWorld)
  int material = 0;
};

std::vector<Tracer::ShapeShading> Tracer::ShadingAt(const FrameGeometry& frame) const {
  std::vector<ShapeShading> table(scene_.shapes.size());
  for (size_t i = 0; i < table.size(); ++i) {
    const Shape& shape = scene_.shapes[i];
    const SurfaceNormals& normals = frame.Normals(static_cast<int>(i));
    ShapeShading& entry = table[i];
    entry.material = shape.material;
    entry.turns = frame.HasNormalTransform(static_cast<int>(i));
    if (!normals.faces.empty()) entry.faceNormals = normals.faces.data();
    if (!normals.vertices.empty()) entry.vertexNormals = normals.vertices.data();
    entry.texture = textures_[static_cast<size_t>(shape.material)].get();
    const ShapeUvs& uvs = *uvs_[i];
    if (entry.texture && !uvs.empty()) entry.uvs = uvs.data();
    if (!colors_[i]->empty()) entry.colors = colors_[i]->data();
    const ShadingMaterial& material = materials_[static_cast<size_t>(shape.material)];
    if (material.pbr) {
      entry.pbr = &material.gltf;
      if (material.gltf.ReadsTexCoord(0) && !uvs.empty()) entry.uvs = uvs.data();
      if (material.gltf.ReadsTexCoord(1) && !uvs1_[i]->empty()) entry.uvs1 = uvs1_[i]->data();
      if (material.gltf.normalTexture && !tangents_[i]->empty()) entry.tangents = tangents_[i]->data();
    }
    const bool meshed = !shape.Mesh().triangles.empty();
    if (meshed && (entry.vertexNormals || entry.VariesDiffuse() || entry.pbr)) {
      entry.triangles = shape.Mesh().triangles.data();
    }
  }
  return table;
}

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
  void FollowBlockedShadowRays(int32_t* sampleHorizon);

 private:
  struct SurfaceHit {
    Float3 position;
    Float3 normal;     // unit shading normal, on the side the ray arrived from
    Float3 faceNormal;  // unit, of the surface itself, on that side: offsets go along it
    Float3 diffuse;     // the material's diffuse colour here (its texture's, where it has one)
    Float3 direction;  // unit direction of the arriving ray
    bool fromInside;   // arrived against the geometric normal (leaving a solid)
    bool unlit;        // its material shows itself whatever lights it (no shadow rays)
    float offset;      // distance that clears the hit point's rounding error
    int shape;
    uint32_t primitive;  // of a mesh: the triangle hit
    int material;
    PbrSurface pbr{Unset{}};  // glTF materials: the BRDF's inputs here (base colour, not `diffuse`)
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
  // The normal a smooth mesh shades this hit with, in object space; zero when flat.
  static Float3 SmoothNormal(const ShapeShading& shape, const RawHit& raw);
  // The diffuse colour at the hit: the material's, times its texture at the hit's
  // interpolated texture coordinates where the shape has them.
  Float3 SurfaceDiffuse(const ShapeShading& shape, const RawHit& raw) const;
  // A normal carried to the world and made unit (kept as it is when already unit and the
  // shape does not turn); zero stays zero. Inline for the common shape that does not turn.
  Float3 ToWorld(int shape, bool turns, const Float3& normal, bool unit = false) const {
    if (turns) return TurnedToWorld(shape, normal);
    if (unit) return normal;  // computed unit in double: kept to the bit
    float length = Length(normal);
    return (length > 0 && std::isfinite(length)) ? normal * (1.0f / length) : Float3{};
  }
  Float3 TurnedToWorld(int shape, const Float3& normal) const;
  // Vectors by reference: passed by value, their packed halves went through the stack
  // and stalled every hit on the store forwarding.
  SurfaceHit MakeHit(const Float3& origin, const Float3& direction, const RawHit& raw, float coneWidth) const;
  // A glTF material's inputs at the hit, its normal map's normal and its coat's.
  void ShadePbr(const ShapeShading& shape, const RawHit& raw, SurfaceHit& hit) const;
  // The hit's ray cone on its triangle's texture coordinates (a point without a cone).
  UvFootprint TextureFootprint(const ShapeShading& shape, const RawHit& raw, const SurfaceHit& hit) const;
  // The hit's normal as normal map `map` tilts it; the hit's normal itself where the map is
  // missing, lacks its texture coordinates, or gives no normal.
  Float3 MappedNormal(const ShapeShading& shape, const RawHit& raw, const SurfaceHit& hit, const PbrTexture& map,
                      std::array<float, 2> uv0, std::array<float, 2> uv1, const UvFootprint& footprint) const;
  Float3 TangentFrameNormal(const ShapeShading& shape, const RawHit& raw, const SurfaceHit& hit, const PbrTexture& map,
                            Float3 texel) const;
  // The hit triangle's direction of increasing u over the normal map's texture coordinates,
  // in object space, and the sign of its bitangent (v's direction against normal x tangent).
  Float3 TriangleTangent(const ShapeShading& shape, const RawHit& raw, int shapeIndex, float* handedness) const;
  // Light arriving at the hit from light i if nothing blocks it; false when the light is
  // behind the surface, or the surface is unlit (then no shadow ray is needed at all).
  bool ShadowRay(const SurfaceHit& hit, size_t light, Float3* direction, float* distance) const;
  // Inline: asked for every lit hit and light.
  Float3 LightContribution(const SurfaceHit& hit, size_t light, Float3 direction, float distance) const {
    const ShadingLight& l = frame_.lights[light];
    const ShadingMaterial& m = (*frame_.materials)[hit.material];
    const Float3 color = m.pbr ? PbrReflected(hit.pbr, m.gltf.constants, direction, hit.normal, -hit.direction)
                               : m.Reflected(direction, hit.normal, hit.direction, hit.diffuse);
    return color * l.intensity * l.Arriving(direction, distance);
  }
  // What the surface shows with no light: the ambient term, and its own emission.
  Float3 Ambient(const SurfaceHit& hit) const;
  Float3 Combine(const SurfaceHit& hit, Float3 local, int depth);
  Float3 CombinePbr(const SurfaceHit& hit, const PbrMaterial& material, Float3 local, int depth);
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

RTCScene Tracer::PixelTracer::SceneAhead(int frame) {
  size_t index = static_cast<size_t>(frame - frame_.frame - 1);
  if (framesAhead_.size() <= index) framesAhead_.resize(index + 1);
  if (!framesAhead_[index]) framesAhead_[index] = frame_.frames->ForFrame(frame);
  return framesAhead_[index]->scene();
}

Tracer::PixelTracer::SurfaceHit Tracer::PixelTracer::MakeHit(const Float3& origin, const Float3& direction,
                                                             const RawHit& raw, float coneWidth) const {
  const int shape = frame_.geometry->ShapeOf(raw.instanceId, raw.geometryId);
  const ShapeShading& shading = frame_.shapes[static_cast<size_t>(shape)];
  // The face's normal (unit, computed in double from the scene), or Embree's for shapes
  // without faces; in object space for a shape that turns or scales.
  Float3 face = shading.faceNormals ? ToWorld(shape, shading.turns, shading.faceNormals[raw.primitiveId], true)
                                    : ToWorld(shape, shading.turns, raw.geometricNormal);
  // A degenerate normal would put NaN into the frame; face the ray instead.
  if (IsZero(face)) face = -direction;
  const bool fromInside = Dot(face, direction) > 0;
  if (fromInside) face = -face;
  // A smooth mesh shades with its interpolated normal, turned to the face's side.
  // Zero (flat) stays zero in the world: only a smooth normal is carried there.
  Float3 normal = face;
  if (shading.vertexNormals) {
    Float3 smooth = SmoothNormal(shading, raw);
    if (!IsZero(smooth)) smooth = ToWorld(shape, shading.turns, smooth);
    if (!IsZero(smooth)) normal = Dot(smooth, face) < 0 ? -smooth : smooth;
  }
  // Every field written once: a default-constructed hit would be zeroed first.
  SurfaceHit hit{origin + direction * raw.t,
                 normal,
                 face,
                 !shading.pbr && shading.VariesDiffuse() ? SurfaceDiffuse(shading, raw)
                                                         : (*frame_.materials)[shading.material].diffuse,
                 direction,
                 fromInside,
                 shading.pbr && shading.pbr->unlit,
                 kRelativeRayOffset * (MaxAbsComponent(origin) + raw.t),
                 shape,
                 raw.primitiveId,
                 shading.material,
                 PbrSurface(Unset{}),
                 coneWidth};
  if (shading.pbr) ShadePbr(shading, raw, hit);
  return hit;
}

void Tracer::PixelTracer::ShadePbr(const ShapeShading& shape, const RawHit& raw, SurfaceHit& hit) const {
  std::array<float, 2> uv0{0, 0}, uv1{0, 0};
  Float3 vertexColor{1, 1, 1};
  const PbrMaterial& material = *shape.pbr;
  UvFootprint footprint;
  if (shape.triangles) {
    if (material.Textured()) footprint = TextureFootprint(shape, raw, hit);
    const auto& corner = shape.triangles[raw.primitiveId];
    const float w = 1.0f - raw.u - raw.v;
    auto interpolate = [&](const std::array<float, 2>* uvs) -> std::array<float, 2> {
      const auto &a = uvs[corner[0]], &b = uvs[corner[1]], &c = uvs[corner[2]];
      return {a[0] * w + b[0] * raw.u + c[0] * raw.v, a[1] * w + b[1] * raw.u + c[1] * raw.v};
    };
    if (shape.uvs) uv0 = interpolate(shape.uvs);
    if (shape.uvs1) uv1 = interpolate(shape.uvs1);
    if (shape.colors) {
      const Float3 &a = shape.colors[corner[0]], &b = shape.colors[corner[1]], &c = shape.colors[corner[2]];
      vertexColor = a * w + b * raw.u + c * raw.v;
    }
  }
  hit.pbr = material.Surface(uv0, uv1, vertexColor, footprint);
  // The coat's normal: its own map over the surface's normal, not over the normal map's.
  if (hit.pbr.clearcoat > 0) {
    hit.pbr.clearcoatNormal = MappedNormal(shape, raw, hit, material.clearcoatNormalTexture, uv0, uv1, footprint);
  }
  hit.normal = MappedNormal(shape, raw, hit, material.normalTexture, uv0, uv1, footprint);
}

// The triangle's texel density is its texture coordinates' area over its area in the
// world: its scene vertices (a deforming mesh's rest pose) as this frame places them.
UvFootprint Tracer::PixelTracer::TextureFootprint(const ShapeShading& shape, const RawHit& raw,
                                                  const SurfaceHit& hit) const {
  UvFootprint footprint;
  if (!(hit.coneWidth > 0)) return footprint;
  const auto& corner = shape.triangles[raw.primitiveId];
  const std::vector<Vec3>& vertices = scene_.shapes[static_cast<size_t>(hit.shape)].Mesh().vertices;
  const Vec3 &p0 = vertices[corner[0]], &p1 = vertices[corner[1]], &p2 = vertices[corner[2]];
  const Vec3 cross = frame_.geometry->AreaToWorld(hit.shape, CrossD(SubtractD(p1, p0), SubtractD(p2, p0)));
  const double worldArea = std::sqrt(DotD(cross, cross));
  const float cosine = Dot(hit.direction, hit.faceNormal);
  if (shape.uvs) footprint.log2Width[0] = Log2UvWidth(hit.coneWidth, cosine, UvArea2(shape.uvs, corner), worldArea);
  if (shape.uvs1) footprint.log2Width[1] = Log2UvWidth(hit.coneWidth, cosine, UvArea2(shape.uvs1, corner), worldArea);
  return footprint;
}

Float3 Tracer::PixelTracer::MappedNormal(const ShapeShading& shape, const RawHit& raw, const SurfaceHit& hit,
                                         const PbrTexture& map, std::array<float, 2> uv0,
                                         std::array<float, 2> uv1, const UvFootprint& footprint) const {
  // A normal map needs the texture coordinates it was painted over.
  const bool mapped = map && shape.triangles && (map.texCoord == 0 ? shape.uvs : shape.uvs1);
  if (!mapped) return hit.normal;
  const Float3 n = TangentFrameNormal(shape, raw, hit, map, map.Sample(map.texCoord == 0 ? uv0 : uv1, footprint));
  return IsZero(n) ? hit.normal : n;
}

// A normal map's normal: the texel (tangent space, [0, 1] codes for [-1, 1], x and y
// scaled) in the frame of the hit's tangent, bitangent and shading normal. The tangent is
// the mesh's (TANGENT) where it has them, else the triangle's direction of increasing u;
// either is made perpendicular to the shading normal. Zero when the frame is degenerate.
Float3 Tracer::PixelTracer::TangentFrameNormal(const ShapeShading& shape, const RawHit& raw, const SurfaceHit& hit,
                                               const PbrTexture& map, Float3 texel) const {
  const auto& corner = shape.triangles[raw.primitiveId];
  Float3 tangent;
  float handedness = 1;
  if (shape.tangents) {
    const float w = 1.0f - raw.u - raw.v;
    const auto &a = shape.tangents[corner[0]], &b = shape.tangents[corner[1]], &c = shape.tangents[corner[2]];
    tangent = Float3{a[0], a[1], a[2]} * w + Float3{b[0], b[1], b[2]} * raw.u + Float3{c[0], c[1], c[2]} * raw.v;
    handedness = a[3] < 0 ? -1.0f : 1.0f;
  } else {
    tangent = TriangleTangent(shape, raw, hit.shape, &handedness);
  }
  tangent = ToWorld(hit.shape, frame_.geometry->HasNormalTransform(hit.shape), tangent);
  const Float3 n = hit.normal;
  tangent = tangent - n * Dot(n, tangent);
  const float length = Length(tangent);
  if (!(length > 1e-12f)) return {};
  tangent = tangent * (1.0f / length);
  // The bitangent follows the shading normal's side, so a surface seen from behind keeps
  // its bumps.
  const Float3 bitangent = Cross(n, tangent) * handedness;
  const float x = (texel.x * 2.0f - 1.0f) * map.amount, y = (texel.y * 2.0f - 1.0f) * map.amount;
  const float z = texel.z * 2.0f - 1.0f;
  const Float3 mapped = tangent * x + bitangent * y + n * z;
  const float mappedLength = Length(mapped);
  return mappedLength > 0 && std::isfinite(mappedLength) ? mapped * (1.0f / mappedLength) : Float3{};
}

Float3 Tracer::PixelTracer::SurfaceDiffuse(const ShapeShading& shape, const RawHit& raw) const {
  const auto& corner = shape.triangles[raw.primitiveId];
  const float w = 1.0f - raw.u - raw.v;
  Float3 diffuse = (*frame_.materials)[shape.material].diffuse;
  if (shape.uvs) {
    const auto &a = shape.uvs[corner[0]], &b = shape.uvs[corner[1]], &c = shape.uvs[corner[2]];
    diffuse = diffuse * shape.texture->Sample(a[0] * w + b[0] * raw.u + c[0] * raw.v,
                                              a[1] * w + b[1] * raw.u + c[1] * raw.v);
  }
  if (shape.colors) {
    const Float3 &a = shape.colors[corner[0]], &b = shape.colors[corner[1]], &c = shape.colors[corner[2]];
    diffuse = diffuse * (a * w + b * raw.u + c * raw.v);
  }
  return diffuse;
}

Float3 Tracer::PixelTracer::SmoothNormal(const ShapeShading& shape, const RawHit& raw) {
  const auto& corner = shape.triangles[raw.primitiveId];
  const Float3 *vertices = shape.vertexNormals, &a = vertices[corner[0]], &b = vertices[corner[1]],
               &c = vertices[corner[2]];
  // A corner without a normal leaves the face flat.
  for (const Float3* n : {&a, &b, &c}) {
    if (n->x == 0 && n->y == 0 && n->z == 0) return {};
  }
  return a * (1.0f - raw.u - raw.v) + b * raw.u + c * raw.v;
}

Float3 Tracer::PixelTracer::TurnedToWorld(int shape, const Float3& normal) const {
  Vec3 world = frame_.geometry->NormalToWorld(shape, {normal.x, normal.y, normal.z});
  double length = std::sqrt(world.x * world.x + world.y * world.y + world.z * world.z);
  return length > 0 ? ToFloat3({world.x / length, world.y / length, world.z / length}) : Float3{};
}

bool Tracer::PixelTracer::ShadowRay(const SurfaceHit& hit, size_t light, Float3* direction,
                                    float* distance) const {
  if (hit.unlit) return false;
  return frame_.lights[light].Toward(hit.position, hit.normal, direction, distance);
}

Float3 Tracer::PixelTracer::Ambient(const SurfaceHit& hit) const {
  const ShadingMaterial& m = (*frame_.materials)[hit.material];
  if (m.pbr) {
    const PbrSurface& s = hit.pbr;
    if (m.gltf.unlit) return s.baseColor;
    // A uniform sky of radiance `ambient` reflects about the diffuse colour and f0 of it.
    const Float3 reflected = s.baseColor * (1.0f - s.metallic) + SurfaceF0(s, m.gltf.constants);
    if (s.clearcoat > 0) {
      // A coat reflects its share of the sky whole, and dims what lies beneath it, emission too.
      const float coat = ClearcoatWeight(s, -hit.direction);
      return (reflected * (1.0f - coat) + Float3{coat, coat, coat}) * (frame_.ambient * s.occlusion) +
             s.emission * (1.0f - coat);
    }
    return reflected * (frame_.ambient * s.occlusion) + s.emission;
  }
  const Float3 ambient = hit.diffuse * frame_.ambient;
  return m.emits ? ambient + m.emission : ambient;
}

// glTF materials: a smooth surface mirrors what it faces, weighted by Fresnel at the
// viewing angle; a transmitting one refracts its share (KHR_materials_transmission), the
// rest of its light as it was. A coat takes its weight of both, and a smooth coat mirrors
// about its own normal. (Under transmission the coat's highlights of lights, in `local`,
// are weighed as the rest of it: a coated glass is rare.)
Float3 Tracer::PixelTracer::CombinePbr(const SurfaceHit& hit, const PbrMaterial& material, Float3 local, int depth) {
  Float3 color = local;
  const Float3 mirror = Reflect(hit.direction, hit.normal);
  const float coat = hit.pbr.clearcoat > 0 ? ClearcoatWeight(hit.pbr, -hit.direction) : 0.0f;
  if (hit.pbr.roughness < PbrMaterial::kMirrorRoughness) {
    const float nDotV = std::max(-Dot(hit.direction, hit.normal), 0.0f);
    const Float3 fresnel = Schlick(SurfaceF0(hit.pbr, material.constants), SurfaceF90(hit.pbr, material.constants), nDotV);
    ++counts_.reflection;
    color += TraceRay(Spawn(hit, false), mirror, depth + 1, hit.coneWidth) * (coat > 0 ? fresnel * (1.0f - coat) : fresnel);
  }
  const float transmitted = material.transmission * (1.0f - hit.pbr.metallic);
  if (transmitted > 0) {
    const float eta = hit.fromInside ? material.indexOfRefraction : 1.0f / material.indexOfRefraction;
    Float3 refracted;
    Float3 through;
    if (!Refract(hit.direction, hit.normal, eta, &refracted)) {  // total internal reflection
      ++counts_.reflection;
      through = TraceRay(Spawn(hit, false), mirror, depth + 1, hit.coneWidth);
    } else {
      ++counts_.refraction;
      through = TraceRay(Spawn(hit, true), refracted, depth + 1, hit.coneWidth);
    }
    color = color * (1.0f - transmitted) + through * (coat > 0 ? transmitted * (1.0f - coat) : transmitted);
  }
  if (coat > 0 && hit.pbr.clearcoatRoughness < PbrMaterial::kMirrorRoughness) {
    ++counts_.reflection;
    color += TraceRay(Spawn(hit, false), Reflect(hit.direction, hit.pbr.clearcoatNormal), depth + 1, hit.coneWidth) * coat;
  }
  // A blended surface covers alpha of the ray; the rest goes straight on past it.
  if (material.blends && hit.pbr.alpha < 1) {
    ++counts_.refraction;
    const Float3 behind = TraceRay(Spawn(hit, true), hit.direction, depth + 1, hit.coneWidth);
    color = color * hit.pbr.alpha + behind * (1.0f - hit.pbr.alpha);
  }
  return color;
}

float Tracer::PixelTracer::BlendTransmittance(Float3 start, Float3 direction, float distance) {
  // Only blended surfaces lie on the way (the occlusion query found nothing else): each
  // closest hit is one of them.
  constexpr int kMaxLayers = 64;
  float through = 1;
  Float3 origin = start;
  float left = distance;
  for (int layer = 0; layer < kMaxLayers && through > 0; ++layer) {
    RTCRayHit rayHit{};
    rayHit.ray.org_x = origin.x, rayHit.ray.org_y = origin.y, rayHit.ray.org_z = origin.z;
    rayHit.ray.dir_x = direction.x, rayHit.ray.dir_y = direction.y, rayHit.ray.dir_z = direction.z;
    rayHit.ray.tnear = 0;
    rayHit.ray.tfar = left;
    rayHit.ray.mask = ~0u;
    rayHit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rayHit.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(frame_.geometry->scene(), &context_.embree, &rayHit);
    if (rayHit.hit.geomID == RTC_INVALID_GEOMETRY_ID) break;
    const float t = HitDistance(rayHit.ray, frame_.geometry->SettlesTies());
    const SurfaceHit hit = MakeHit(origin, direction,
                                   {t,
                                    {rayHit.hit.Ng_x, rayHit.hit.Ng_y, rayHit.hit.Ng_z},
                                    rayHit.hit.instID[0],
                                    rayHit.hit.geomID,
                                    rayHit.hit.primID,
                                    rayHit.hit.u,
                                    rayHit.hit.v},
                                   0.0f);
    const ShadingMaterial& m = (*frame_.materials)[hit.material];
    if (!m.pbr || !m.gltf.blends) return 0;  // not a blended surface after all: it blocks
    through *= 1.0f - hit.pbr.alpha;
    origin = Spawn(hit, true);
    left = distance - Length(origin - start);
    if (!(left > 0)) break;
  }
  return through;
}

// Local shading weighted against mirror reflection and refraction, Whitted style.
Float3 Tracer::PixelTracer::Combine(const SurfaceHit& hit, Float3 local, int depth) {
  const ShadingMaterial& m = (*frame_.materials)[hit.material];
  if (depth >= frame_.maxDepth || !m.MirrorsOrRefracts()) return local;
  if (m.pbr) return CombinePbr(hit, m.gltf, local, depth);
  Float3 color = local * (1.0f - m.reflectivity - m.transparency);
  Float3 mirror = Reflect(hit.direction, hit.normal);
  if (m.reflectivity > 0) {
    ++counts_.reflection;
    color += TraceRay(Spawn(hit, false), mirror, depth + 1, hit.coneWidth) * m.reflectivity;
  }
  if (m.transparency > 0) {
    float eta = hit.fromInside ? m.indexOfRefraction : 1.0f / m.indexOfRefraction;
    Float3 refracted;
    if (!Refract(hit.direction, hit.normal, eta, &refracted)) {  // total internal reflection
      ++counts_.reflection;
      color += TraceRay(Spawn(hit, false), mirror, depth + 1, hit.coneWidth) * m.transparency;
    } else {
      ++counts_.refraction;
      color += TraceRay(Spawn(hit, true), refracted, depth + 1, hit.coneWidth) * m.transparency;
    }
  }
  return color;
}

Float3 Tracer::PixelTracer::TraceRay(Float3 origin, Float3 direction, int depth, float coneWidth) {
  RTCRayHit rayHit{};
  rayHit.ray.org_x = origin.x, rayHit.ray.org_y = origin.y, rayHit.ray.org_z = origin.z;
  rayHit.ray.dir_x = direction.x, rayHit.ray.dir_y = direction.y, rayHit.ray.dir_z = direction.z;
  rayHit.ray.tnear = 0;
  rayHit.ray.tfar = kInfinity;
  rayHit.ray.mask = ~0u;
  rayHit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rayHit.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(frame_.geometry->scene(), &context_.embree, &rayHit);
  if (rayHit.hit.geomID == RTC_INVALID_GEOMETRY_ID) {
    if (horizons_) horizons_->Segment(horizons_->lane, origin, direction, kInfinity);
    return frame_.background;
  }

  const float hitDistance = HitDistance(rayHit.ray, frame_.geometry->SettlesTies());
  SurfaceHit hit = MakeHit(origin, direction,
                           {hitDistance,
                            {rayHit.hit.Ng_x, rayHit.hit.Ng_y, rayHit.hit.Ng_z},
                            rayHit.hit.instID[0],
                            rayHit.hit.geomID,
                            rayHit.hit.primID,
                            rayHit.hit.u,
                            rayHit.hit.v},
                           RayCone{coneWidth, frame_.camera.pixelCone.spread}.WidthAt(hitDistance));
  // The surface first: a moving one settles the horizon and spares the segment's test.
  if (horizons_) {
    NoteSurface(horizons_->lane, hit);
    horizons_->Segment(horizons_->lane, origin, direction, hitDistance);
  }
  Float3 local = Ambient(hit);
  for (size_t light = 0; light < frame_.lights.size(); ++light) {
    Float3 toLight;
    float distance;
    if (!ShadowRay(hit, light, &toLight, &distance)) continue;
    RTCRay shadow{};
    Float3 start = Spawn(hit, false);
    shadow.org_x = start.x, shadow.org_y = start.y, shadow.org_z = start.z;
    shadow.dir_x = toLight.x, shadow.dir_y = toLight.y, shadow.dir_z = toLight.z;
    shadow.tnear = 0;
    shadow.tfar = distance;
    shadow.mask = ~0u;
    if (!frame_.shadows) {  // the light reaches whatever faces it: no ray, no horizon
      local += LightContribution(hit, light, toLight, distance);
      continue;
    }
    ++counts_.shadow;
    const RTCRay query = shadow;
    rtcOccluded1(frame_.geometry->scene(), &context_.embree, &shadow);
    bool blocked = shadow.tfar < 0;
    if (!blocked) {
      const Float3 arriving = LightContribution(hit, light, toLight, distance);
      local += frame_.anyBlend ? arriving * BlendTransmittance(start, toLight, distance) : arriving;
    }
    if (!horizons_) continue;
    const int lane = horizons_->lane;
    if (!blocked) {
      horizons_->LightSegment(lane, light, start, toLight, distance);
      continue;
    }
    int blocker;
    if (horizons_->BlockedShadowMayClear(lane, {start, toLight, distance}, &blocker)) {
      walks_.push_back({horizons_->sample + static_cast<uint32_t>(lane), blocker, query});
    }
  }
  return Combine(hit, local, depth);
}

template <int Width>
void Tracer::PixelTracer::TracePrimaryPacket(const uint32_t* pixel, const int* sample, int count,
                                             Float3* color) {
  alignas(64) int valid[Width] = {};
  alignas(64) typename RayPacket<Width>::RayHit packet{};
  const auto width = static_cast<uint32_t>(scene_.render.width);
  for (int lane = 0; lane < count; ++lane) {
    float px, py;
    SamplePosition(pixel[lane] % width, pixel[lane] / width, sample[lane],
                   frame_.samplesPerPixel, &px, &py);
    Float3 o, d;
    frame_.camera.Ray(px, py, &o, &d);
    valid[lane] = -1;
    packet.ray.org_x[lane] = o.x;
    packet.ray.org_y[lane] = o.y;
    packet.ray.org_z[lane] = o.z;
    packet.ray.dir_x[lane] = d.x, packet.ray.dir_y[lane] = d.y, packet.ray.dir_z[lane] = d.z;
    packet.ray.tnear[lane] = 0;
    packet.ray.tfar[lane] = kInfinity;
    packet.ray.mask[lane] = ~0u;
    packet.hit.geomID[lane] = RTC_INVALID_GEOMETRY_ID;
    packet.hit.instID[0][lane] = RTC_INVALID_GEOMETRY_ID;
  }
  counts_.primary += count;
  RayPacket<Width>::Intersect(valid, frame_.geometry->scene(), &context_.embree, &packet);

  SurfaceHit hits[Width];
  bool hasHit[Width] = {};
  bool lit[Width] = {};  // some light reaches the hit
  for (int lane = 0; lane < count; ++lane) {
    hasHit[lane] = packet.hit.geomID[lane] != RTC_INVALID_GEOMETRY_ID;
    Float3 origin{packet.ray.org_x[lane], packet.ray.org_y[lane], packet.ray.org_z[lane]};
    Float3 direction{packet.ray.dir_x[lane], packet.ray.dir_y[lane], packet.ray.dir_z[lane]};
    if (!hasHit[lane]) {
      if (horizons_) horizons_->EyeSegment(lane, origin, direction, kInfinity);
      color[lane] = frame_.background;
      continue;
    }
    const float hitDistance = HitDistance(packet.ray, lane, frame_.geometry->SettlesTies());
    hits[lane] = MakeHit(origin, direction,
                         {hitDistance,
                          {packet.hit.Ng_x[lane], packet.hit.Ng_y[lane], packet.hit.Ng_z[lane]},
                          packet.hit.instID[0][lane],
                          packet.hit.geomID[lane],
                          packet.hit.primID[lane],
                          packet.hit.u[lane],
                          packet.hit.v[lane]},
                         frame_.camera.pixelCone.WidthAt(hitDistance));
    if (horizons_) {
      NoteSurface(lane, hits[lane]);
      horizons_->EyeSegment(lane, origin, direction, hitDistance);
    }
    color[lane] = Ambient(hits[lane]);
  }

  // Shadow rays of one light for the whole packet: they share a target, so they stay coherent.
  for (size_t light = 0; light < frame_.lights.size(); ++light) {
    alignas(64) int shadowValid[Width] = {};
    alignas(64) typename RayPacket<Width>::Ray shadow{};
    Float3 toLight[Width];
    float distance[Width];
    int shadowCount = 0;
    for (int lane = 0; lane < count; ++lane) {
      if (!hasHit[lane] || !ShadowRay(hits[lane], light, &toLight[lane], &distance[lane])) continue;
      Float3 start = Spawn(hits[lane], false);
      shadowValid[lane] = -1;
      shadow.org_x[lane] = start.x, shadow.org_y[lane] = start.y, shadow.org_z[lane] = start.z;
      shadow.dir_x[lane] = toLight[lane].x;
      shadow.dir_y[lane] = toLight[lane].y;
      shadow.dir_z[lane] = toLight[lane].z;
      shadow.tnear[lane] = 0;
      shadow.tfar[lane] = distance[lane];
      shadow.mask[lane] = ~0u;
      ++shadowCount;
    }
    if (shadowCount == 0) continue;
    if (!frame_.shadows) {  // the light reaches whatever faces it: no ray, no horizon
      for (int lane = 0; lane < count; ++lane) {
        if (!shadowValid[lane]) continue;
        color[lane] += LightContribution(hits[lane], light, toLight[lane], distance[lane]);
        lit[lane] = true;
      }
      continue;
    }
    counts_.shadow += shadowCount;
    alignas(64) typename RayPacket<Width>::Ray query;
    if (horizons_) query = shadow;  // as asked: Embree overwrites tfar with the answer
    RayPacket<Width>::Occluded(shadowValid, frame_.geometry->scene(), &context_.embree, &shadow);
    int blocked[Width] = {};
    for (int lane = 0; lane < count; ++lane) {
      if (!shadowValid[lane]) continue;
      blocked[lane] = shadow.tfar[lane] < 0;
      if (blocked[lane]) continue;
      const Float3 arriving = LightContribution(hits[lane], light, toLight[lane], distance[lane]);
      color[lane] += frame_.anyBlend ? arriving * BlendTransmittance({shadow.org_x[lane], shadow.org_y[lane], shadow.org_z[lane]},
                                                                     toLight[lane], distance[lane])
                                     : arriving;
      lit[lane] = true;
    }
    if (horizons_) ShadowHorizons<Width>(light, query, shadowValid, blocked);
  }
  for (int lane = 0; horizons_ && lane < count; ++lane) {
    if (!hasHit[lane] || lit[lane]) continue;
    const RaySegment eye{{packet.ray.org_x[lane], packet.ray.org_y[lane], packet.ray.org_z[lane]},
                         {packet.ray.dir_x[lane], packet.ray.dir_y[lane], packet.ray.dir_z[lane]},
                         HitDistance(packet.ray, lane, frame_.geometry->SettlesTies())};
    SettleUnlitMovingSphere(lane, hits[lane], eye);
  }
  if (!frame_.anySecondary) return;
  for (int lane = 0; lane < count; ++lane) {
    if (!hasHit[lane]) continue;
    if (horizons_) horizons_->lane = lane;
    color[lane] = Combine(hits[lane], color[lane], 0);
  }
}

template <int Width>
void Tracer::PixelTracer::ShadowHorizons(size_t light, const typename RayPacket<Width>::Ray& query,
                                         const int* valid, const int* blocked) {
  for (int lane = 0; lane < Width; ++lane) {
    if (!valid[lane]) continue;
    const RaySegment segment{{query.org_x[lane], query.org_y[lane], query.org_z[lane]},
                             {query.dir_x[lane], query.dir_y[lane], query.dir_z[lane]},
                             query.tfar[lane]};
    if (!blocked[lane]) {
      horizons_->LightSegment(lane, light, segment.origin, segment.direction, segment.length);
    } else if (int blocker; horizons_->BlockedShadowMayClear(lane, segment, &blocker)) {
      RTCRay ray{};
      ray.org_x = query.org_x[lane], ray.org_y = query.org_y[lane], ray.org_z = query.org_z[lane];
      ray.dir_x = query.dir_x[lane], ray.dir_y = query.dir_y[lane], ray.dir_z = query.dir_z[lane];
      ray.tnear = query.tnear[lane], ray.tfar = query.tfar[lane], ray.mask = query.mask[lane];
      walks_.push_back({horizons_->sample + static_cast<uint32_t>(lane), blocker, ray});
    }
  }
}

void Tracer::PixelTracer::FollowBlockedShadowRays(int32_t* sampleHorizon) {
  for (const BlockedShadowRay& walk : walks_) {
    int32_t& horizon = sampleHorizon[walk.sample];
    const RaySegment segment{{walk.ray.org_x, walk.ray.org_y, walk.ray.org_z},
                             {walk.ray.dir_x, walk.ray.dir_y, walk.ray.dir_z},
                             walk.ray.tfar};
    int blocker = walk.blocker;
    for (int frame = frame_.frame + 1; frame < horizon; ++frame) {
      frame = horizons_->oracle->FirstNotSurelyBlocked(segment, frame, horizon, &blocker);
      if (frame >= horizon) break;
      if (horizons_->oracle->OnlyTranslatingSpheresMove()) {
        horizon = frame;
        break;
      }
      RTCRay ray = walk.ray;
      rtcOccluded1(SceneAhead(frame), &context_.embree, &ray);
      if (ray.tfar >= 0) horizon = frame;  // clear: the light reaches the pixel again
    }
  }
  walks_.clear();
}

void Tracer::PixelTracer::SettleUnlitMovingSphere(int lane, const SurfaceHit& hit, const RaySegment& eye) {
  const HorizonOracle& oracle = *horizons_->oracle;
  const int sphere = oracle.SphereOfShape(hit.shape);
  // Ties need no care: where the rule holds, nothing else is on the ray as near as the
  // sphere (see UnlitSphereHolds).
  if (sphere < 0 || hit.fromInside) return;
  const ShapeShading& shading = frame_.shapes[static_cast<size_t>(hit.shape)];
  if (shading.VariesDiffuse() || shading.pbr) return;
  if ((*frame_.materials)[hit.material].MirrorsOrRefracts()) return;
  // Each light the hit faces was blocked: by which moving sphere, to follow it.
  const int mover = oracle.MoverOfSphere(sphere);
  blockers_.resize(frame_.lights.size());
  for (size_t light = 0; light < frame_.lights.size(); ++light) {
    Float3 direction;
    float distance;
    blockers_[light] = -1;
    if (!ShadowRay(hit, light, &direction, &distance)) continue;
    const int blocker = oracle.MoverThatMayBlock({Spawn(hit, false), direction, distance}, mover);
    if (blocker < 0 || oracle.SphereOfMover(blocker) < 0) return;  // a still shape, or one not followed
    blockers_[light] = oracle.SphereOfMover(blocker);
  }
  // Nothing but the sample's camera and its surface has lowered its horizon so far: the
  // lights it faces are blocked, and their rays were not followed with the horizon at the
  // next frame already.
  int& horizon = horizons_->horizon[lane];
  horizon = oracle.UnlitSphereHolds(sphere, eye, frame_.lights, blockers_.data(),
                                    std::min(oracle.CameraCap(), oracle.LightCap()));
  horizons_->EyeSegment(lane, eye.origin, eye.direction, eye.length, mover);
}

void Tracer::PixelTracer::NoteSurface(int lane, const SurfaceHit& hit) {
  horizons_->Surface(lane, hit.shape, hit.primitive);
}

Tracer::Tracer(const EmbreeDevice& device, const Scene& scene, TracingThreads& threads, BuildStop stop)
    : device_(device),
      scene_(scene),
      surfaceRules_(MakeSurfaceRules()),
      geometry_(device, scene, stop, RulesOf(surfaceRules_)),
      threads_(threads),
      packetWidth_(NativePacketWidth(device.get())) {
  uvs_ = PerShapeOncePerMesh<ShapeUvs>(scene.shapes, [](const Shape& shape) {
    ShapeUvs uvs;
    for (const auto& uv : shape.Mesh().uvs) uvs.push_back({static_cast<float>(uv[0]), static_cast<float>(uv[1])});
    return uvs;
  });
  colors_ = PerShapeOncePerMesh<ShapeColors>(scene.shapes, [](const Shape& shape) {
    ShapeColors colors;
    for (const Vec3& color : shape.Mesh().colors) colors.push_back(ToFloat3(color));
    return colors;
  });
  // Only what some glTF material reads: most meshes have neither.
  auto readBy = [&scene](const Shape& shape, auto reads) {
    const Material& material = scene.materials[static_cast<size_t>(shape.material)];
    return material.pbr && reads(*material.pbr);
  };
  uvs1_ = PerShapeOncePerMesh<ShapeUvs>(scene.shapes, [&](const Shape& shape) {
    ShapeUvs uvs;
    if (!readBy(shape, [](const MetallicRoughness& m) { return m.ReadsTexCoord(1); })) return uvs;
    for (const auto& uv : shape.Mesh().uvs1) uvs.push_back({static_cast<float>(uv[0]), static_cast<float>(uv[1])});
    return uvs;
  });
  tangents_ = PerShapeOncePerMesh<ShapeTangents>(scene.shapes, [&](const Shape& shape) {
    ShapeTangents tangents;
    if (!readBy(shape, [](const MetallicRoughness& m) { return m.normalTexture.has_value(); })) return tangents;
    for (const auto& t : shape.Mesh().tangents) {
      tangents.push_back({static_cast<float>(t[0]), static_cast<float>(t[1]), static_cast<float>(t[2]),
                          static_cast<float>(t[3])});
    }
    return tangents;
  });
  // Materials never change over frames: converted for shading once, not per task.
  materials_ = MakeMaterials(scene, [this](const Texture& texture, TextureImage::Encoding encoding) {
    return LoadPbrTexture(texture, encoding);
  });
  // Only the images a material uses are loaded, once.
  for (const Material& material : scene.materials) {
    textures_.push_back(material.diffuseTexture ? std::make_unique<TextureImage>(*material.diffuseTexture) : nullptr);
  }
}

std::vector<std::unique_ptr<SurfaceRule>> Tracer::MakeSurfaceRules() {
  std::vector<std::unique_ptr<SurfaceRule>> rules;
  for (const Shape& shape : scene_.shapes) {
    rules.push_back(GltfSurfaceRule::For(shape, scene_.materials[static_cast<size_t>(shape.material)],
                                         [this](const Texture& texture, TextureImage::Encoding encoding) {
                                           return LoadPbrTexture(texture, encoding);
                                         }));
  }
  return rules;
}

const TextureImage* Tracer::LoadPbrTexture(const Texture& texture, TextureImage::Encoding encoding) {
  // Materials that share an image (an occlusion map packed with metal and roughness) share
  // its decoding; wrap, filter and mip levels are part of what is decoded.
  const std::string key = texture.asset + "|" + texture.file.string() + "|" + texture.image + "|" +
                          std::to_string(static_cast<int>(texture.wrapS)) + std::to_string(static_cast<int>(texture.wrapT)) +
                          std::to_string(static_cast<int>(texture.filter)) + (texture.mipmaps ? "m" : "");
  auto& image = pbrTextures_[{key, encoding}];
  if (!image) image = std::make_unique<TextureImage>(texture, encoding);
  return image.get();
}

namespace {
void SearchFan(const HorizonOracle& oracle, SegmentFan& fan, int32_t* sampleHorizon,
               const int32_t* exceptMover = nullptr) {
  if (fan.empty()) return;
  fan.Index();
  oracle.FanFirstMeetings(fan, sampleHorizon, exceptMover);
}
}  // namespace

void Tracer::TracePixels(int frame, const uint32_t* pixels, size_t pixelCount, float* rgb,
                         int window, int32_t* horizons) {
  std::unique_ptr<HorizonOracle> oracle;
  if (window > 0 && horizons) {
    // Blocked shadow rays are followed only over frames the geometry keeps placed, when
    // placing one is dear (deforming meshes): the frame and those ahead of it stay cached.
    const int walkFrames = geometry_.HasDeformingMeshes() ? static_cast<int>(geometry_.CachedFrames()) - 1 : -1;
    oracle = std::make_unique<HorizonOracle>(
        scene_, frame, window, [this](size_t shape) { return geometry_.Deforming(shape); }, walkFrames);
    // A moving camera changes every pixel next frame: no ray tree can say otherwise.
    if (oracle->CameraCap() == frame + 1) {
      std::fill(horizons, horizons + pixelCount, frame + 1);
      oracle.reset();
    }
  }
  FrameContext context{frame,
                       geometry_.ForFrame(frame),
                       &geometry_,
                       MakeCamera(scene_, frame),
                       MakeLights(scene_, frame),
                       &materials_,
                       {},
                       ToFloat3(scene_.background),
                       scene_.render.maxDepth,
                       scene_.render.samplesPerPixel,
                       scene_.AnyMaterialReflects() || scene_.AnyMaterialRefracts(),
                       scene_.render.shadows,
                       AnyMaterialBlends(scene_),
                       static_cast<float>(scene_.render.ambient)};
  context.shapes = ShadingAt(*context.geometry);
  const int spp = context.samplesPerPixel;
  // Camera rays, and shadow rays toward lights that have a position, are searched for
  // their horizons frame by frame in fans (segment_fan.h); the cones of the movers' bounds
  // are shared by all chunks.
  std::unique_ptr<FanCones> eyeCones;
  std::vector<std::unique_ptr<FanCones>> lightCones(context.lights.size());
  if (oracle && oracle->MoverCount() > 0) {
    auto conesAround = [&oracle](Float3 point) {
      const Vec3 at{point.x, point.y, point.z};
      return std::make_unique<FanCones>(*oracle, at, oracle->FanSlack(at));
    };
    if (!context.camera.orthographic) eyeCones = conesAround(context.camera.origin);
    for (size_t light = 0; light < context.lights.size(); ++light) {
      if (const Float3* at = context.lights[light].Position()) lightCones[light] = conesAround(*at);
    }
  }
  const size_t chunk = PixelsPerChunk(pixelCount, threads_.ThreadCount(), oracle != nullptr);
  threads_.ParallelFor(pixelCount, chunk, [&](size_t begin, size_t end) {
    const uint64_t cpuAtStart = ThreadCpuNanoseconds();
    PixelTracer tracer(context, scene_);
    // Every (pixel, sample) of the chunk, in order, then packets over them. The
    // buffers live per thread: allocating them per chunk showed up in profiles. With one
    // sample a pixel, the items are the pixels themselves, all of sample 0.
    thread_local std::vector<uint32_t> itemPixel;
    thread_local std::vector<int> itemSample;
    thread_local std::vector<Float3> sampleColor;
    const size_t items = (end - begin) * static_cast<size_t>(spp);
    const uint32_t* itemPixels = pixels + begin;
    if (spp == 1) {
      itemSample.assign(items, 0);
    } else {
      itemPixel.clear();
      itemSample.clear();
      for (size_t i = begin; i < end; ++i) {
        for (int s = 0; s < spp; ++s) {
          itemPixel.push_back(pixels[i]);
          itemSample.push_back(s);
        }
      }
      itemPixels = itemPixel.data();
    }
    sampleColor.resize(items);
    thread_local std::vector<int32_t> sampleHorizon;
    HorizonTracker tracker;
    // Fans live per thread too: their buffers grow to a chunk's segments once.
    thread_local SegmentFan eyeFan;
    thread_local std::vector<SegmentFan> lightFans;
    thread_local std::vector<int32_t> eyeExcept;
    if (oracle) {
      sampleHorizon.resize(items);
      eyeExcept.assign(items, -1);
      tracker.eyeExcept = eyeExcept.data();
      tracker.oracle = oracle.get();
      eyeFan.Reset(eyeCones.get());
      lightFans.resize(lightCones.size());
      for (size_t light = 0; light < lightCones.size(); ++light) lightFans[light].Reset(lightCones[light].get());
      tracker.eyeFan = &eyeFan;
      tracker.lightFans = &lightFans;
      tracer.TrackHorizons(&tracker);
    }
    WithPacketWidth(packetWidth_, [&](auto packetWidth) {
      constexpr int kWidth = decltype(packetWidth)::value;
      for (size_t item = 0; item < items; item += kWidth) {
        const int lanes = static_cast<int>(std::min<size_t>(kWidth, items - item));
        if (oracle) tracker.Reset(), tracker.sample = static_cast<uint32_t>(item);
        tracer.TracePrimaryPacket<kWidth>(itemPixels + item, &itemSample[item], lanes, &sampleColor[item]);
        for (int lane = 0; oracle && lane < lanes; ++lane) {
          sampleHorizon[item + lane] = tracker.horizon[lane];
        }
      }
    });
    // The fans' searches first: blocked shadow rays are followed only up to the horizons
    // they leave, the dearest search last.
    if (oracle) {
      SearchFan(*oracle, eyeFan, sampleHorizon.data(), eyeExcept.data());
      for (SegmentFan& fan : lightFans) SearchFan(*oracle, fan, sampleHorizon.data());
      tracer.FollowBlockedShadowRays(sampleHorizon.data());
    }
    // A pixel is valid while all its samples are.
    for (size_t i = begin; oracle && i < end; ++i) {
      int32_t horizon = oracle->Unbounded();
      for (int s = 0; s < spp; ++s) horizon = std::min(horizon, sampleHorizon[(i - begin) * spp + s]);
      horizons[i] = horizon;
    }
    // Average in sample order, so the sum's rounding is the same wherever the pixel goes.
    for (size_t i = begin; i < end; ++i) {
      Float3 sum;
      for (int s = 0; s < spp; ++s) sum += sampleColor[(i - begin) * spp + s];
      Float3 mean = sum * (1.0f / spp);
      float* out = rgb + 3 * i;
      out[0] = StorableChannel(mean.x);
      out[1] = StorableChannel(mean.y);
      out[2] = StorableChannel(mean.z);
    }
    const RayCounts& c = tracer.counts();
    primary_ += c.primary;
    shadow_ += c.shadow;
    reflection_ += c.reflection;
    refraction_ += c.refraction;
    cpuNanoseconds_ += ThreadCpuNanoseconds() - cpuAtStart;
  });
}

void Tracer::SetPacketWidth(int width) {
  if (width != 8 && width != 16) {
    throw std::invalid_argument("packet width " + std::to_string(width) + "; expected 8 or 16");
  }
  packetWidth_ = width;
}

void Tracer::TraceFrame(int frame, float* rgb) {
  size_t count = static_cast<size_t>(scene_.render.width) * scene_.render.height;
  std::vector<uint32_t> pixels(count);
  for (size_t i = 0; i < count; ++i) pixels[i] = static_cast<uint32_t>(i);
  TracePixels(frame, pixels.data(), count, rgb);
}

RayCounts Tracer::Counts() const {
  RayCounts c;
  c.primary = primary_;
  c.shadow = shadow_;
  c.reflection = reflection_;
  c.refraction = refraction_;
  return c;
}

Float3 Tracer::PixelTracer::TriangleTangent(const ShapeShading& shape, const RawHit& raw, int shapeIndex,
                                            float* handedness) const {
  const auto& corner = shape.triangles[raw.primitiveId];
  const std::array<float, 2>* uvs = shape.pbr->normalTexture.texCoord == 0 ? shape.uvs : shape.uvs1;
  const std::vector<Vec3>& vertices = scene_.shapes[static_cast<size_t>(shapeIndex)].Mesh().vertices;
  const Vec3 &p0 = vertices[corner[0]], &p1 = vertices[corner[1]], &p2 = vertices[corner[2]];
  const Vec3 e1 = SubtractD(p1, p0), e2 = SubtractD(p2, p0);
  const double du1 = uvs[corner[1]][0] - uvs[corner[0]][0], dv1 = uvs[corner[1]][1] - uvs[corner[0]][1];
  const double du2 = uvs[corner[2]][0] - uvs[corner[0]][0], dv2 = uvs[corner[2]][1] - uvs[corner[0]][1];
  const double det = du1 * dv2 - du2 * dv1;
  if (det == 0) return {};
  // dp/du and dp/dv, solved from the two edges.
  const Vec3 dpdu{(dv2 * e1.x - dv1 * e2.x) / det, (dv2 * e1.y - dv1 * e2.y) / det, (dv2 * e1.z - dv1 * e2.z) / det};
  const Vec3 dpdv{(du1 * e2.x - du2 * e1.x) / det, (du1 * e2.y - du2 * e1.y) / det, (du1 * e2.z - du2 * e1.z) / det};
  // glTF's v runs down the image while a normal map's green points up it: unmirrored
  // texture coordinates have n x t along -dp/dv (w = +1, as TANGENT has it); mirrored
  // ones flip the bitangent (w = -1), as MikkTSpace's sign says.
  const Vec3 normal = CrossD(e1, e2);
  *handedness = DotD(CrossD(normal, dpdu), dpdv) < 0 ? 1.0f : -1.0f;
  return ToFloat3(dpdu);
}

}  // namespace tcfarm
