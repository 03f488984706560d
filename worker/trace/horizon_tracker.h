// The horizons of the samples of one packet, folded in as their rays are cast (only when
// `exact` asks for horizons): each ray segment and each surface seen can only lower them.
// See horizons.h for what a horizon is and why each rule below keeps it safe.
#pragma once

#include <algorithm>

#include "worker/embree/ray_packets.h"
#include "worker/trace/float3.h"
#include "worker/trace/horizons.h"
#include "worker/trace/segment_fan.h"

namespace tcfarm {

struct HorizonTracker {
  const HorizonOracle* oracle = nullptr;
  int horizon[kMaxPacketWidth];  // by lane of the packet being traced
  int lane = 0;  // the sample whose secondary rays are being traced
  // Segments that fan out from the camera's eye, or toward light i, are recorded in their
  // fan and searched frame by frame once the chunk is traced (FanFirstMeetings), where
  // given; `sample` numbers the packet's lanes in the chunk.
  SegmentFan* eyeFan = nullptr;
  std::vector<SegmentFan>* lightFans = nullptr;  // by light; a fan without cones: none
  uint32_t sample = 0;
  // By sample in the chunk: the mover its camera segment's search leaves out (-1: none),
  // for the eye fan's search; set wherever eyeFan is.
  int32_t* eyeExcept = nullptr;

  void Reset() {
    for (int& h : horizon) h = oracle->CameraCap();
  }
  void Segment(int forLane, Float3 origin, Float3 direction, float length) {
    if (horizon[forLane] == oracle->frame() + 1) return;  // cannot get any earlier
    horizon[forLane] = oracle->FirstMeeting({origin, direction, length}, horizon[forLane]);
  }
  // exceptMover: a mover the segment's search leaves out (-1: none), the one whose
  // surface it ends on (see HorizonOracle::UnlitSphereHolds).
  void EyeSegment(int forLane, Float3 origin, Float3 direction, float length, int exceptMover = -1) {
    FanSegment(eyeFan, forLane, origin, direction, length, exceptMover, eyeExcept);
  }
  void LightSegment(int forLane, size_t light, Float3 origin, Float3 direction, float length) {
    FanSegment(lightFans ? &(*lightFans)[light] : nullptr, forLane, origin, direction, length);
  }
  // exceptOf: the fan's record of each sample's exceptMover, where one is given.
  void FanSegment(SegmentFan* fan, int forLane, Float3 origin, Float3 direction, float length,
                  int exceptMover = -1, int32_t* exceptOf = nullptr) {
    if (horizon[forLane] == oracle->frame() + 1) return;
    const RaySegment segment{origin, direction, length};
    if (fan && fan->cones() && (exceptMover < 0 || exceptOf)) {
      if (!oracle->NearAnyMover(segment)) return;
      const uint32_t at = sample + static_cast<uint32_t>(forLane);
      if (fan->Add(at, segment)) {
        if (exceptMover >= 0) exceptOf[at] = exceptMover;
        return;
      }
    }
    horizon[forLane] = oracle->FirstMeeting(segment, horizon[forLane], exceptMover);
  }
  // A surface seen: the pixel may change when the surface does (a deforming mesh's parts
  // that hold still do not), or when a light does.
  void Surface(int forLane, int shape, uint32_t primitive) {
    horizon[forLane] = std::min({horizon[forLane], oracle->SurfaceChange(shape, primitive), oracle->LightCap()});
  }
  // A shadow ray found blocked at the traced frame: the light adds nothing, and keeps
  // adding nothing for as long as the ray stays blocked, whoever blocks it. True when the
  // ray is to be followed frame by frame ahead (the tracer's FollowBlockedShadowRays,
  // once the chunk's other rays have set the horizons), instead of the pixel being traced
  // again at every frame a moving shadow covers it. Not needed when the horizon is the
  // next frame already, nor when no moving shape's bounds come near the ray at the
  // traced frame: what blocks it never moves, so it stays blocked.
  // A walk goes no further than the oracle's WalkEnd: the horizon is capped there first,
  // and where that is the next frame (deforming meshes) the ray is not followed at all.
  // `blocker`: the moving sphere that likely blocks it (-1: not known).
  bool BlockedShadowMayClear(int forLane, const RaySegment& segment, int* blocker) {
    if (horizon[forLane] <= oracle->frame() + 1) return false;
    const int mover = oracle->MoverThatMayBlock(segment);
    if (mover < 0) return false;
    *blocker = oracle->SphereOfMover(mover);
    horizon[forLane] = std::min(horizon[forLane], oracle->WalkEnd());
    return horizon[forLane] > oracle->frame() + 1;  // else no frame is left to follow it over
  }
};

}  // namespace tcfarm
