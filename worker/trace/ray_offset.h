// How far secondary rays start off the surface they leave.
#pragma once

namespace tcfarm {

// Secondary rays start this fraction of the hit's coordinate magnitude (|origin| + t)
// off the surface: float rounding of the hit point grows with that magnitude, so a
// relative offset clears it at any scene scale where a fixed epsilon would not.
// 1e-5 is ~170 float ulps: well above Embree's intersection error, well below any
// feature a scene can usefully resolve. The horizons (horizons.cpp) place shadow rays
// where the tracer will, and the bare Embree loop offsets its own alike.
constexpr float kRelativeRayOffset = 1e-5f;

}  // namespace tcfarm
