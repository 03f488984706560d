#include "worker/embree/surface_filter.h"

#include "worker/embree/closest_hit.h"

namespace tcfarm {
namespace {

// Embree's triangle normal points as the counter-clockwise one does (out of the front): a
// ray travelling along it meets the back.
bool MeetsBack(const RTCFilterFunctionNArguments* args, unsigned lane) {
  const float dot = RTCRayN_dir_x(args->ray, args->N, lane) * RTCHitN_Ng_x(args->hit, args->N, lane) +
                    RTCRayN_dir_y(args->ray, args->N, lane) * RTCHitN_Ng_y(args->hit, args->N, lane) +
                    RTCRayN_dir_z(args->ray, args->N, lane) * RTCHitN_Ng_z(args->hit, args->N, lane);
  return dot > 0;
}

void ApplyRule(const RTCFilterFunctionNArguments* args, bool occlusion) {
  const auto* filter = static_cast<const SurfaceFilter*>(args->geometryUserPtr);
  for (unsigned lane = 0; lane < args->N; ++lane) {
    if (args->valid[lane] == 0) continue;
    if (!filter->rule->Keeps(RTCHitN_primID(args->hit, args->N, lane), RTCHitN_u(args->hit, args->N, lane),
                             RTCHitN_v(args->hit, args->N, lane), MeetsBack(args, lane), occlusion)) {
      args->valid[lane] = 0;
    }
  }
}

void FilterIntersection(const RTCFilterFunctionNArguments* args) {
  ApplyRule(args, false);
  if (static_cast<const SurfaceFilter*>(args->geometryUserPtr)->settleTies) SettleTies(args);
}

void FilterOcclusion(const RTCFilterFunctionNArguments* args) { ApplyRule(args, true); }

}  // namespace

void SetSurfaceFilters(RTCGeometry geometry, const SurfaceFilter* filter) {
  if (!filter) return;
  if (!filter->rule) {
    if (filter->settleTies) rtcSetGeometryIntersectFilterFunction(geometry, SettleTies);
    return;
  }
  rtcSetGeometryUserData(geometry, const_cast<SurfaceFilter*>(filter));
  rtcSetGeometryIntersectFilterFunction(geometry, FilterIntersection);
  rtcSetGeometryOccludedFilterFunction(geometry, FilterOcclusion);
}

}  // namespace tcfarm
