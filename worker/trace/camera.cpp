#include "worker/trace/camera.h"

#include <cmath>

namespace tcfarm {
namespace {

uint32_t HashPixel(uint32_t x, uint32_t y) {
  uint32_t h = x * 0x8da6b343u ^ y * 0xd8163841u;
  h ^= h >> 16;
  h *= 0x7feb352du;
  h ^= h >> 15;
  h *= 0x846ca68bu;
  h ^= h >> 16;
  return h;
}

}  // namespace

PerspectiveCamera MakeCamera(const Scene& scene, int frame) {
  const CameraPose pose = scene.camera.At(frame);
  const Vec3& position = pose.position;
  Vec3 forward = NormalizeD(SubtractD(pose.lookAt, position));
  Vec3 right = NormalizeD(CrossD(forward, pose.up));
  Vec3 up = CrossD(right, forward);
  const RenderSettings& r = scene.render;
  // Half the image plane's height: at distance 1 (perspective), or in world units.
  double tanHalf = scene.camera.orthographic ? scene.camera.orthographicHeight / 2
                                             : std::tan(scene.camera.verticalFovDegrees * M_PI / 360.0);
  double aspect = static_cast<double>(r.width) / r.height;
  PerspectiveCamera camera;
  camera.origin = ToFloat3(position);
  camera.forward = ToFloat3(forward);
  camera.right = ToFloat3({right.x * tanHalf * aspect, right.y * tanHalf * aspect, right.z * tanHalf * aspect});
  camera.up = ToFloat3({up.x * tanHalf, up.y * tanHalf, up.z * tanHalf});
  camera.width = static_cast<float>(r.width);
  camera.height = static_cast<float>(r.height);
  camera.orthographic = scene.camera.orthographic;
  if (camera.orthographic) {
    camera.pixelCone.width = static_cast<float>(scene.camera.orthographicHeight / r.height);
  } else {
    camera.pixelCone.spread = static_cast<float>(scene.camera.verticalFovDegrees * M_PI / 180.0 / r.height);
  }
  return camera;
}

void SampleInPixel(uint32_t x, uint32_t y, int sample, float* px, float* py) {
  constexpr double kG = 1.32471795724474602596;  // the plastic number: R2's generator
  uint32_t h = HashPixel(x, y);
  double u = (h & 0xffff) / 65536.0 + sample / kG;
  double v = (h >> 16) / 65536.0 + sample / (kG * kG);
  *px = static_cast<float>(x + (u - std::floor(u)));
  *py = static_cast<float>(y + (v - std::floor(v)));
}

}  // namespace tcfarm
