#include "worker/trace/tracer.h"
#include "worker/trace/barycentric.h"
#include "worker/trace/pixel_tracer.h"

#include <algorithm>
#include <climits>
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

// The chunk's pixels (positions 0 .. count-1 of `pixels`) in the order packets take them.
// A sparse set (exact's due pixels, a search's) by 4x4 tile, tiles in rows, pixels in a
// tile as given: a packet of 16 then holds neighbours, whose rays stay together in the
// tree, where the set's next 16 in row order scatter across the picture (measured: 90 ns
// a pixel down to 82 on exact's set at frame 30 of the twelve spheres). A run of
// consecutive pixels (a full frame's rows) as given: whole rows traced 16 wide ran about
// 7 % faster than tiles. A stable counting sort, linear in the pixels and the tiles their
// rows span. Packets change no pixel's bits (each sample is traced to the same bits
// whatever its lanes).
constexpr uint32_t kTileSide = 4;

// Leaves `order` empty for a run of consecutive pixels: the order given.
void TileOrder(const uint32_t* pixels, size_t count, uint32_t width, std::vector<uint32_t>& order,
               std::vector<uint32_t>& tileStart) {
  order.clear();
  if (count == 0 || (pixels[count - 1] - pixels[0] == count - 1 && std::is_sorted(pixels, pixels + count))) return;
  order.resize(count);
  const uint32_t tilesAcross = (width + kTileSide - 1) / kTileSide;
  uint32_t firstRow = UINT32_MAX, lastRow = 0;
  for (size_t i = 0; i < count; ++i) {
    firstRow = std::min(firstRow, pixels[i] / width / kTileSide);
    lastRow = std::max(lastRow, pixels[i] / width / kTileSide);
  }
  auto tileOf = [&](uint32_t pixel) {
    return (pixel / width / kTileSide - firstRow) * tilesAcross + pixel % width / kTileSide;
  };
  tileStart.assign(size_t{lastRow - firstRow + 1} * tilesAcross + 1, 0);
  for (size_t i = 0; i < count; ++i) ++tileStart[tileOf(pixels[i]) + 1];
  for (size_t t = 1; t < tileStart.size(); ++t) tileStart[t] += tileStart[t - 1];
  for (size_t i = 0; i < count; ++i) order[tileStart[tileOf(pixels[i])]++] = static_cast<uint32_t>(i);
}

// A frame holds finite values only. Light beyond float range (a huge intensity at a tiny
// distance) saturates to the largest float rather than going black; NaN, which no scene
// should produce, becomes 0.
float StorableChannel(float value) {
  if (std::isnan(value)) return 0.0f;
  return std::clamp(value, -std::numeric_limits<float>::max(), std::numeric_limits<float>::max());
}


std::vector<const SurfaceRule*> RulesOf(const std::vector<std::unique_ptr<SurfaceRule>>& rules) {
  std::vector<const SurfaceRule*> pointers;
  for (const auto& rule : rules) pointers.push_back(rule.get());
  return pointers;
}

bool AnyMaterialBlends(const Scene& scene) {
  return std::any_of(scene.materials.begin(), scene.materials.end(), [](const Material& m) { return m.Blends(); });
}

uint64_t ThreadCpuNanoseconds() {
  timespec now{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
  return static_cast<uint64_t>(now.tv_sec) * 1000000000u + static_cast<uint64_t>(now.tv_nsec);
}

}  // namespace

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
    if (!colors_[i]->empty()) entry.colors = colors_[i]->data();
    bool readsTriangles = false;
    WithModel(materials_[static_cast<size_t>(shape.material)], [&](const auto& m) {
      if (m.ReadsTexCoord(0) && !uvs_[i]->empty()) entry.uvs = uvs_[i]->data();
      if (m.ReadsTexCoord(1) && !uvs1_[i]->empty()) entry.uvs1 = uvs1_[i]->data();
      if (m.ReadsTangents() && !tangents_[i]->empty()) entry.tangents = tangents_[i]->data();
      readsTriangles = m.ReadsTriangles();
    });
    const bool meshed = !shape.Mesh().triangles.empty();
    if (meshed && (entry.vertexNormals || entry.VariesDiffuse() || readsTriangles)) {
      entry.triangles = shape.Mesh().triangles.data();
    }
  }
  return table;
}

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
  SurfaceHit hit{origin + direction * raw.t,
                 normal,
                 face,
                 direction,
                 fromInside,
                 false,
                 kRelativeRayOffset * (MaxAbsComponent(origin) + raw.t),
                 shape,
                 raw.primitiveId,
                 shading.material,
                 {},  // Shade writes it
                 coneWidth};
  WithModel(MaterialOf(hit), [&](const auto& m) {
    hit.unlit = m.Unlit();
    m.Shade(*this, shading, raw, hit);
  });
  return hit;
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

Float3 Tracer::PixelTracer::Combine(const SurfaceHit& hit, Float3 local, int depth) {
  return WithModel(MaterialOf(hit), [&](const auto& m) {
    if (depth >= frame_.maxDepth || !m.MirrorsOrRefracts()) return local;
    return m.Combine(*this, hit, SurfaceOf(m, hit.surface), local, depth);
  });
}

float Tracer::PixelTracer::BlendTransmittance(Float3 start, Float3 direction, float distance) {
  // Only blended surfaces lie on the way (the occlusion query found nothing else): each
  // closest hit is one of them.
  constexpr int kMaxLayers = 64;
  float through = 1;
  Float3 origin = start;
  float left = distance;
  for (int layer = 0; layer < kMaxLayers && through > 0; ++layer) {
    const std::optional<RawHit> raw = ClosestHit(origin, direction, left);
    if (!raw) break;
    const SurfaceHit hit = MakeHit(origin, direction, *raw, 0.0f);
    const bool blends = WithModel(MaterialOf(hit), [&](const auto& m) {
      if (!m.Blends()) return false;
      through *= 1.0f - m.Coverage(SurfaceOf(m, hit.surface));
      return true;
    });
    if (!blends) return 0;  // not a blended surface after all: it blocks
    origin = Spawn(hit, true);
    left = distance - Length(origin - start);
    if (!(left > 0)) break;
  }
  return through;
}

std::optional<Tracer::PixelTracer::RawHit> Tracer::PixelTracer::ClosestHit(Float3 origin, Float3 direction,
                                                                          float farthest) {
  RTCRayHit rayHit{};
  rayHit.ray.org_x = origin.x, rayHit.ray.org_y = origin.y, rayHit.ray.org_z = origin.z;
  rayHit.ray.dir_x = direction.x, rayHit.ray.dir_y = direction.y, rayHit.ray.dir_z = direction.z;
  rayHit.ray.tnear = 0;
  rayHit.ray.tfar = farthest;
  rayHit.ray.mask = ~0u;
  rayHit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rayHit.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(frame_.geometry->scene(), &context_.embree, &rayHit);
  if (rayHit.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;
  return RawHit{HitDistance(rayHit.ray, frame_.geometry->SettlesTies()),
                {rayHit.hit.Ng_x, rayHit.hit.Ng_y, rayHit.hit.Ng_z},
                rayHit.hit.instID[0],
                rayHit.hit.geomID,
                rayHit.hit.primID,
                rayHit.hit.u,
                rayHit.hit.v};
}

Float3 Tracer::PixelTracer::TraceRay(Float3 origin, Float3 direction, int depth, float coneWidth) {
  const std::optional<RawHit> raw = ClosestHit(origin, direction, kInfinity);
  if (!raw) {
    if (horizons_) horizons_->Segment(horizons_->lane, origin, direction, kInfinity);
    return frame_.background;
  }
  const float hitDistance = raw->t;
  SurfaceHit hit = MakeHit(origin, direction, *raw,
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
      walks_.push_back({horizons_->sample + static_cast<uint32_t>(lane), blocker, RayOfLane(query, lane)});
    }
  }
}

// The walks go a packet at a time, frame by frame: each lane first skips the frames a
// moving sphere surely blocks it at, then the lanes at the earliest frame left ask Embree
// there together (neighbouring shadow rays toward one light, as coherent as the packets
// that found them blocked). A lane stops at the first frame it clears at, which becomes
// its sample's horizon, or at that horizon, which other rays may lower meanwhile.
template <int Width>
void Tracer::PixelTracer::FollowBlockedShadowRays(int32_t* sampleHorizon) {
  const HorizonOracle& oracle = *horizons_->oracle;
  for (size_t first = 0; first < walks_.size(); first += Width) {
    const int lanes = static_cast<int>(std::min<size_t>(Width, walks_.size() - first));
    const BlockedShadowRay* walk = walks_.data() + first;
    int next[Width], blocker[Width];
    bool walking[Width];
    for (int lane = 0; lane < lanes; ++lane) {
      next[lane] = frame_.frame + 1, blocker[lane] = walk[lane].blocker, walking[lane] = true;
    }
    // Past the frames a moving sphere surely blocks the lane at: the next frame to ask
    // Embree, or none (the lane ends, at its horizon or where it clears).
    auto advance = [&](int lane) {
      int32_t& horizon = sampleHorizon[walk[lane].sample];
      const RTCRay& ray = walk[lane].ray;
      const RaySegment segment{{ray.org_x, ray.org_y, ray.org_z}, {ray.dir_x, ray.dir_y, ray.dir_z}, ray.tfar};
      if (next[lane] < horizon) next[lane] = oracle.FirstNotSurelyBlocked(segment, next[lane], horizon, &blocker[lane]);
      if (next[lane] < horizon && oracle.OnlyTranslatingSpheresMove()) horizon = next[lane];
      walking[lane] = next[lane] < horizon;
    };
    for (;;) {
      int earliest = INT_MAX;
      for (int lane = 0; lane < lanes; ++lane) {
        if (walking[lane]) advance(lane);
        if (walking[lane]) earliest = std::min(earliest, next[lane]);
      }
      if (earliest == INT_MAX) break;
      typename RayPacket<Width>::Ray packet{};
      int valid[Width] = {};
      for (int lane = 0; lane < lanes; ++lane) {
        if (walking[lane] && next[lane] == earliest) valid[lane] = -1, SetLane(packet, lane, walk[lane].ray);
      }
      RayPacket<Width>::Occluded(valid, SceneAhead(earliest), &context_.embree, &packet);
      for (int lane = 0; lane < lanes; ++lane) {
        if (!valid[lane]) continue;
        if (packet.tfar[lane] >= 0) {  // clear: the light reaches the pixel again
          sampleHorizon[walk[lane].sample] = std::min(sampleHorizon[walk[lane].sample], earliest);
          walking[lane] = false;
        } else {
          ++next[lane];
        }
      }
    }
  }
  walks_.clear();
}

template void Tracer::PixelTracer::FollowBlockedShadowRays<8>(int32_t*);
template void Tracer::PixelTracer::FollowBlockedShadowRays<16>(int32_t*);

void Tracer::PixelTracer::SettleUnlitMovingSphere(int lane, const SurfaceHit& hit, const RaySegment& eye) {
  const HorizonOracle& oracle = *horizons_->oracle;
  const int sphere = oracle.SphereOfShape(hit.shape);
  // Ties need no care: where the rule holds, nothing else is on the ray as near as the
  // sphere (see UnlitSphereHolds).
  if (sphere < 0 || hit.fromInside) return;
  const ShapeShading& shading = frame_.shapes[static_cast<size_t>(hit.shape)];
  if (WithModel(MaterialOf(hit), [&](const auto& m) { return m.VariesOver(shading) || m.MirrorsOrRefracts(); })) {
    return;
  }
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
      uvs_(UvTable(scene, 0)),
      uvs1_(UvTable(scene, 1)),
      surfaceRules_(MakeSurfaceRules()),
      geometry_(device, scene, stop, RulesOf(surfaceRules_)),
      threads_(threads),
      packetWidth_(NativePacketWidth(device.get())) {
  colors_ = PerShapeOncePerMesh<ShapeColors>(scene.shapes, [](const Shape& shape) {
    ShapeColors colors;
    for (const Vec3& color : shape.Mesh().colors) colors.push_back(ToFloat3(color));
    return colors;
  });
  // Only where a material reads them: most meshes have none.
  tangents_ = PerShapeOncePerMesh<ShapeTangents>(scene.shapes, [&](const Shape& shape) {
    ShapeTangents tangents;
    if (!scene.materials[static_cast<size_t>(shape.material)].ReadsTangents()) return tangents;
    for (const auto& t : shape.Mesh().tangents) {
      tangents.push_back({static_cast<float>(t[0]), static_cast<float>(t[1]), static_cast<float>(t[2]),
                          static_cast<float>(t[3])});
    }
    return tangents;
  });
  // Materials never change over frames: converted for shading once, not per task.
  materials_ = MakeMaterials(scene, [this](const Texture& texture, TextureImage::Encoding encoding) {
    return LoadTexture(texture, encoding);
  });
}

std::vector<std::shared_ptr<const Tracer::ShapeUvs>> Tracer::UvTable(const Scene& scene, int set) {
  return PerShapeOncePerMesh<ShapeUvs>(scene.shapes, [&scene, set](const Shape& shape) {
    ShapeUvs uvs;
    const Material& material = scene.materials[static_cast<size_t>(shape.material)];
    // The second set only where a material reads it: most meshes have none.
    if (set == 1 && !material.ReadsTexCoord(1)) return uvs;
    for (const auto& uv : set == 1 ? shape.Mesh().uvs1 : shape.Mesh().uvs) {
      uvs.push_back({static_cast<float>(uv[0]), static_cast<float>(uv[1])});
    }
    return uvs;
  });
}

std::vector<std::unique_ptr<SurfaceRule>> Tracer::MakeSurfaceRules() {
  std::vector<std::unique_ptr<SurfaceRule>> rules;
  for (size_t i = 0; i < scene_.shapes.size(); ++i) {
    const Shape& shape = scene_.shapes[i];
    rules.push_back(MakeSurfaceRule(shape, scene_.materials[static_cast<size_t>(shape.material)], {uvs_[i], uvs1_[i]},
                                    [this](const Texture& texture, TextureImage::Encoding encoding) {
                                      return LoadTexture(texture, encoding);
                                    }));
  }
  return rules;
}

const TextureImage* Tracer::LoadTexture(const Texture& texture, TextureImage::Encoding encoding) {
  // Materials that share an image (an occlusion map packed with metal and roughness) share
  // its decoding; wrap, filter and mip levels are part of what is decoded.
  const std::string key = texture.asset + "|" + texture.file.string() + "|" + texture.image + "|" +
                          std::to_string(static_cast<int>(texture.wrapS)) + std::to_string(static_cast<int>(texture.wrapT)) +
                          std::to_string(static_cast<int>(texture.filter)) + (texture.mipmaps ? "m" : "");
  auto& image = textureImages_[{key, encoding}];
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
    // Where a mesh deforms, a frame ahead is dear to place (the mesh posed and refit):
    // blocked shadow rays are followed only over the frames the geometry keeps placed
    // anyway (less the traced frame and the one before it), so that each frame is placed
    // once for all the tasks that walk over it; and only while one segment is in flight,
    // traced frame after frame. Tasks of several segments at once (exact's segments side
    // by side) need more frames than the geometry keeps, and walks there push out the
    // frames the other segments trace, to be placed again and again. On a walking
    // character of 50,000 triangles (640x480, 48 frames, one worker) the walks took
    // `auto`'s traced ratio (one segment) from 0.138 to 0.116 at 0.36 of brute force's
    // CPU before and 0.35 after, while `exact` in segments of 10 side by side went from
    // 0.39 to 0.52 walking.
    int walkFrames = -1;
    if (geometry_.HasDeformingMeshes()) {
      walkFrames = OneSegmentInFlight(frame) ? std::max(0, static_cast<int>(geometry_.CachedFrames()) - 2) : 0;
    }
    oracle = std::make_unique<HorizonOracle>(
        scene_, frame, window, [this](size_t shape) { return geometry_.Deforming(shape); }, walkFrames);
    // A moving camera changes every pixel next frame: no ray tree can say otherwise.
    if (oracle->CameraCap() == frame + 1) {
      std::fill(horizons, horizons + pixelCount, frame + 1);
      oracle.reset();
    }
  }
  // Placing the frame (posing its deforming meshes) counts in the tracing CPU, as placing
  // the frames ahead that blocked shadow rays are followed over does.
  const uint64_t placingStart = ThreadCpuNanoseconds();
  std::shared_ptr<const FrameGeometry> placed = geometry_.ForFrame(frame);
  cpuNanoseconds_ += ThreadCpuNanoseconds() - placingStart;
  FrameContext context{frame,
                       std::move(placed),
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
    // Every (pixel, sample) of the chunk, pixels in the order TileOrder gives, then
    // packets over them. The buffers live per thread: allocating them per chunk showed up
    // in profiles. With one sample a pixel and the order given, the items are the pixels
    // themselves, all of sample 0.
    thread_local std::vector<uint32_t> order, tileStart;
    thread_local std::vector<uint32_t> itemPixel;
    thread_local std::vector<int> itemSample;
    thread_local std::vector<Float3> sampleColor;
    TileOrder(pixels + begin, end - begin, static_cast<uint32_t>(scene_.render.width), order, tileStart);
    // The chunk position of the pixel of rank k in that order.
    auto positionOf = [&](size_t k) { return order.empty() ? k : size_t{order[k]}; };
    const size_t items = (end - begin) * static_cast<size_t>(spp);
    const uint32_t* itemPixels = pixels + begin;
    if (spp == 1 && order.empty()) {
      itemSample.assign(items, 0);
    } else {
      itemPixel.clear();
      itemSample.clear();
      for (size_t k = 0; k < end - begin; ++k) {
        for (int s = 0; s < spp; ++s) {
          itemPixel.push_back(pixels[begin + positionOf(k)]);
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
      WithPacketWidth(packetWidth_, [&](auto packetWidth) {
        tracer.FollowBlockedShadowRays<decltype(packetWidth)::value>(sampleHorizon.data());
      });
    }
    // A pixel is valid while all its samples are. Its samples are items k * spp .. for
    // its rank k in the tile order.
    for (size_t k = 0; oracle && k < end - begin; ++k) {
      int32_t horizon = oracle->Unbounded();
      for (int s = 0; s < spp; ++s) horizon = std::min(horizon, sampleHorizon[k * spp + s]);
      horizons[begin + positionOf(k)] = horizon;
    }
    // Average in sample order, so the sum's rounding is the same wherever the pixel goes.
    for (size_t k = 0; k < end - begin; ++k) {
      Float3 sum;
      for (int s = 0; s < spp; ++s) sum += sampleColor[k * spp + s];
      Float3 mean = sum * (1.0f / spp);
      float* out = rgb + 3 * (begin + positionOf(k));
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

bool Tracer::OneSegmentInFlight(int frame) {
  std::lock_guard<std::mutex> lock(recentMutex_);
  const size_t slots = recentTracedFrames_.size();
  recentTracedFrames_[recentTraces_++ % slots] = frame;
  // Oldest first: a segment goes forward a frame or two at a time (two where another
  // worker took all of a frame); segments side by side, or a new job, jump.
  const size_t known = std::min(recentTraces_, slots);
  for (size_t i = 1; i < known; ++i) {
    const int step = recentTracedFrames_[(recentTraces_ - known + i) % slots] -
                     recentTracedFrames_[(recentTraces_ - known + i - 1) % slots];
    if (step < 0 || step > 2) return false;
  }
  return true;
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

}  // namespace tcfarm
