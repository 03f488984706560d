// The rule that settles ties between surfaces a ray meets at the same distance.
//
// Coplanar faces (a decal on a wall, a quad lying on a floor, two overlapping triangles
// of one mesh) give a ray two hits at bit-identical distances. Embree keeps whichever it
// happens to meet first, and its traversal order depends on the ray's packet mates, the
// packet's active lanes and the frame's tree of placed instances: the same pixel could
// see the floor in a full frame and the quad in a sparse one. Every closest-hit query
// therefore passes a ClosestHitContext, and where surfaces may coincide over an area
// (embree/tie_candidates.h) every geometry carries SettleTies as its intersection filter:
// of hits at the same distance the one with the lowest (shape, primitive) wins, whatever
// order they are met in.
#pragma once

#include <embree3/rtcore.h>

namespace tcfarm {

class FrameGeometry;

// Embree's context with the frame whose geometry the query traverses (the shape of an
// earlier hit is looked up in it). Embree hands the same pointer to the filter.
struct ClosestHitContext {
  RTCIntersectContext embree;
  const FrameGeometry* frame = nullptr;

  explicit ClosestHitContext(const FrameGeometry* frameGeometry) : frame(frameGeometry) {
    rtcInitIntersectContext(&embree);
  }
};

// The distance of a query's closest hit. Where the tie rule is on, a ray's tfar ends a
// little beyond it (see SettleTies) and the hit's distance travels in `id`.
inline float HitDistance(const RTCRay& ray, bool settlesTies) {
  if (!settlesTies) return ray.tfar;
  float distance;
  static_assert(sizeof distance == sizeof ray.id);
  __builtin_memcpy(&distance, &ray.id, sizeof distance);
  return distance;
}
// Of lane `lane` of a packet (RTCRay8, RTCRay16).
template <typename Rays>
inline float HitDistance(const Rays& rays, int lane, bool settlesTies) {
  if (!settlesTies) return rays.tfar[lane];
  float distance;
  __builtin_memcpy(&distance, &rays.id[lane], sizeof distance);
  return distance;
}

// The intersection filter of every geometry a ClosestHitContext query may meet. The
// distance of the hit kept so far travels in the ray's `id` field (Embree hands the
// filter the candidate's distance in tfar and keeps the earlier one to itself); a query
// that uses this rule must not use `id` for anything else, and reads its hit's distance
// with HitDistance, not from tfar.
void SettleTies(const RTCFilterFunctionNArguments* args);

}  // namespace tcfarm
