// The camera of a frame, perspective or orthographic: the ray through any point of the
// image, and where a pixel's samples fall inside it.
#pragma once

#include <cstdint>

#include "proto/scene/scene.h"
#include "worker/trace/float3.h"
#include "worker/trace/ray_cone.h"

namespace tcfarm {

struct PerspectiveCamera {
  // right and up span half the image plane: at distance 1 for a perspective camera, in
  // world units for an orthographic one.
  Float3 origin, forward, right, up;
  float width, height;
  bool orthographic = false;
  // A pixel's ray cone: perspective, from a point, spreading by the vertical field of view
  // over the image's height; orthographic, as wide as a pixel everywhere.
  RayCone pixelCone;

  // The ray through image point (px, py), in pixels from the top left: its origin and
  // unit direction.
  void Ray(float px, float py, Float3* rayOrigin, Float3* direction) const {
    float sx = 2.0f * px / width - 1.0f;
    float sy = 1.0f - 2.0f * py / height;
    if (orthographic) {
      *rayOrigin = origin + right * sx + up * sy;
      *direction = forward;
      return;
    }
    *rayOrigin = origin;
    *direction = Normalize(forward + right * sx + up * sy);
  }
};

// The camera at `frame`, its basis built in double: far from the origin the difference
// position - look_at loses digits in float.
PerspectiveCamera MakeCamera(const Scene& scene, int frame);

// Where sample `sample` of pixel (x, y) falls: the pixel centre for one sample, else an R2
// low-discrepancy sequence rotated by a hash of the pixel. Seeded by pixel, not frame, so
// a pixel that sees nothing change keeps its bits from frame to frame.
// Inline for the pixel centre: asked for every camera ray. SampleInPixel: the others.
void SampleInPixel(uint32_t x, uint32_t y, int sample, float* px, float* py);
inline void SamplePosition(uint32_t x, uint32_t y, int sample, int samplesPerPixel, float* px, float* py) {
  if (samplesPerPixel == 1) {
    *px = x + 0.5f;
    *py = y + 0.5f;
    return;
  }
  SampleInPixel(x, y, sample, px, py);
}

}  // namespace tcfarm
