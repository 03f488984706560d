#include "worker/embree/closest_hit.h"

#include <cstring>
#include <tuple>

#include "worker/embree/scene_geometry.h"

namespace tcfarm {
namespace {

float AsFloat(unsigned bits) {
  float value;
  std::memcpy(&value, &bits, sizeof value);
  return value;
}

unsigned AsBits(float value) {
  unsigned bits;
  std::memcpy(&bits, &value, sizeof bits);
  return bits;
}

// Embree culls a tree node whose entry distance, as it rounds it, lies beyond the ray's
// tfar: the flat box of a face coplanar with the hit kept so far can be culled although
// its face lies at exactly that distance, and whether it is depends on the traversal
// path (single ray or packet). Keeping tfar this far beyond the kept hit lets every such
// face be offered to the filter; hits farther than the kept one are refused there.
// 2^-16 relative is hundreds of float ulps, far more than the traversal's rounding.
constexpr float kTieSlack = 1.0f + 1.0f / 65536.0f;

// Shapes in scene order, then primitives in mesh order: an order every frame and every
// worker agrees on, unlike geometry or instance ids alone.
std::tuple<int, unsigned> HitKey(const FrameGeometry& frame, RTCHitN* hit, unsigned n,
                                 unsigned lane) {
  return {frame.ShapeOf(RTCHitN_instID(hit, n, lane, 0), RTCHitN_geomID(hit, n, lane)),
          RTCHitN_primID(hit, n, lane)};
}

}  // namespace

void SettleTies(const RTCFilterFunctionNArguments* args) {
  const auto* context = reinterpret_cast<const ClosestHitContext*>(args->context);
  // Embree passes the ray with its hit so far: the intersect filter's ray is a RayHit.
  auto* rayHit = reinterpret_cast<RTCRayHitN*>(args->ray);
  RTCHitN* kept = RTCRayHitN_HitN(rayHit, args->N);
  for (unsigned lane = 0; lane < args->N; ++lane) {
    if (args->valid[lane] == 0) continue;
    const float candidate = RTCRayN_tfar(args->ray, args->N, lane);
    unsigned& keptDistance = RTCRayN_id(args->ray, args->N, lane);
    const bool anyKept = RTCHitN_geomID(kept, args->N, lane) != RTC_INVALID_GEOMETRY_ID;
    const bool farther = anyKept && candidate > AsFloat(keptDistance);
    const bool tie = anyKept && candidate == AsFloat(keptDistance);
    if (farther || (tie && !(HitKey(*context->frame, args->hit, args->N, lane) <
                             HitKey(*context->frame, kept, args->N, lane)))) {
      args->valid[lane] = 0;  // Embree puts tfar back as it was
      continue;
    }
    keptDistance = AsBits(candidate);
    RTCRayN_tfar(args->ray, args->N, lane) = candidate * kTieSlack;
  }
}

}  // namespace tcfarm
