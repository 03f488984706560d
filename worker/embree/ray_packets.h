// Embree's ray packets by width. The tracer and the bare loop cast 16 rays a packet where
// Embree runs 16-wide packets natively (AVX-512): 7 % faster for the tracer and 17 % for
// the bare loop than 8-wide packets on the same machine (tracer_bench), with the same
// bits in every frame. Elsewhere Embree would split a 16-wide packet, so they cast 8.
#pragma once

#include <embree3/rtcore.h>

#include <type_traits>

namespace tcfarm {

constexpr int kMaxPacketWidth = 16;

// One width's packet types and calls, named once: RayPacket<Width>::RayHit, ::Ray,
// ::Intersect(valid, scene, context, packet) and ::Occluded(...).
template <typename RayHitType, typename RayType,
          void (*IntersectCall)(const int*, RTCScene, RTCIntersectContext*, RayHitType*),
          void (*OccludedCall)(const int*, RTCScene, RTCIntersectContext*, RayType*)>
struct EmbreePacket {
  using RayHit = RayHitType;
  using Ray = RayType;
  static void Intersect(const int* valid, RTCScene scene, RTCIntersectContext* context, RayHit* packet) {
    IntersectCall(valid, scene, context, packet);
  }
  static void Occluded(const int* valid, RTCScene scene, RTCIntersectContext* context, Ray* packet) {
    OccludedCall(valid, scene, context, packet);
  }
};

template <int Width>
struct RayPacket;
template <>
struct RayPacket<8> : EmbreePacket<RTCRayHit8, RTCRay8, rtcIntersect8, rtcOccluded8> {};
template <>
struct RayPacket<16> : EmbreePacket<RTCRayHit16, RTCRay16, rtcIntersect16, rtcOccluded16> {};

// One lane of a packet's rays as a single ray, and back: a shadow ray found blocked in a
// packet is kept alone, and asked again with others in a packet of its own.
template <typename PacketRay>
RTCRay RayOfLane(const PacketRay& packet, int lane) {
  RTCRay ray{};
  ray.org_x = packet.org_x[lane], ray.org_y = packet.org_y[lane], ray.org_z = packet.org_z[lane];
  ray.dir_x = packet.dir_x[lane], ray.dir_y = packet.dir_y[lane], ray.dir_z = packet.dir_z[lane];
  ray.tnear = packet.tnear[lane], ray.tfar = packet.tfar[lane], ray.mask = packet.mask[lane];
  ray.time = packet.time[lane], ray.id = packet.id[lane], ray.flags = packet.flags[lane];
  return ray;
}
template <typename PacketRay>
void SetLane(PacketRay& packet, int lane, const RTCRay& ray) {
  packet.org_x[lane] = ray.org_x, packet.org_y[lane] = ray.org_y, packet.org_z[lane] = ray.org_z;
  packet.dir_x[lane] = ray.dir_x, packet.dir_y[lane] = ray.dir_y, packet.dir_z[lane] = ray.dir_z;
  packet.tnear[lane] = ray.tnear, packet.tfar[lane] = ray.tfar, packet.mask[lane] = ray.mask;
  packet.time[lane] = ray.time, packet.id[lane] = ray.id, packet.flags[lane] = ray.flags;
}

// 16 where the device runs 16-wide packets natively, 8 elsewhere.
inline int NativePacketWidth(RTCDevice device) {
  return rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED) ? 16 : 8;
}

// Calls trace(std::integral_constant<int, W>{}) for W = width (16, else 8): the packet
// loop is compiled once per width and chosen once per chunk, not per packet.
template <typename Trace>
void WithPacketWidth(int width, Trace&& trace) {
  if (width == 16) {
    trace(std::integral_constant<int, 16>{});
  } else {
    trace(std::integral_constant<int, 8>{});
  }
}

}  // namespace tcfarm
