// Validity horizons (the `exact` strategy): for a pixel traced at frame a, the first frame
// h > a at which something that changes could alter it. The pixel's ray tree at frame a
// (camera, shadow, reflection and refraction segments; a miss is a segment to infinity)
// is tested against conservative bounds of every moving shape at every frame a .. a+W:
// if no moving shape's bounds meet the ray tree at frame f, nothing the pixel sees has
// changed at f, so its value at f is bit-identical to its value at a (tracing is
// deterministic and the sample pattern is seeded by pixel).
//
// Bounds are spheres padded beyond the ray offsets; a shape's bounds at frame a itself
// count as meeting at a+1 (it may move away: a pixel in its shadow changes then). A camera
// that changes caps every horizon, and so does a light that changes, for every pixel
// that sees a surface (the light's direction or intensity reaches it).
#pragma once

#include <cstdint>
#include <vector>

#include "embree/device.h"
#include "scene/scene.h"
#include "trace/float3.h"

namespace tcfarm {

struct RaySegment {
  Float3 origin;
  Float3 direction;  // unit
  float length;      // infinity for a ray that escapes the scene
};

class HorizonOracle {
 public:
  // window: frames after `frame` to look at; horizons are capped at frame + window + 1,
  // meaning "valid through the whole window".
  HorizonOracle(const EmbreeDevice& device, const Scene& scene, int frame, int window);

  int frame() const { return frame_; }
  int window() const { return window_; }
  int Unbounded() const { return frame_ + window_ + 1; }
  // Cap for every pixel (the camera moves).
  int CameraCap() const { return cameraCap_; }
  // Cap for a pixel whose ray tree reaches a surface (a light changes).
  int LightCap() const { return lightCap_; }
  // The first frame at which a moving shape's bounds meet the segment, else Unbounded().
  int FirstMeeting(const RaySegment& segment) const;

 private:
  void AddProxies(const EmbreeDevice& device, const Scene& scene, int lastFrame);

  int frame_, window_;
  int cameraCap_, lightCap_;
  SceneHandle proxies_;
  std::vector<int> proxyHorizon_;  // per proxy primitive: the horizon its meeting implies
  bool anyProxy_ = false;
};

}  // namespace tcfarm
