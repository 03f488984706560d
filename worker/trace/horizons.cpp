#include "trace/horizons.h"

#include <algorithm>
#include <cmath>

namespace tcfarm {
namespace {

// Proxy radii grow by this fraction of the shape's coordinate magnitude: more than the
// tracer's relative ray offset (1e-5) and float rounding of hit points, so a segment that
// grazes a shape always meets its proxy.
constexpr double kRelativeProxyPad = 1e-4;

struct BoundingSphere {
  Vec3 center;
  double radius;
};

BoundingSphere BoundsOf(const std::vector<Vec3>& points) {
  Vec3 lo = points.front(), hi = points.front();
  for (const Vec3& p : points) {
    for (int i = 0; i < 3; ++i) {
      lo[i] = std::min(lo[i], p[i]);
      hi[i] = std::max(hi[i], p[i]);
    }
  }
  Vec3 c{(lo.x + hi.x) / 2, (lo.y + hi.y) / 2, (lo.z + hi.z) / 2};
  double r2 = 0;
  for (const Vec3& p : points) {
    r2 = std::max(r2, (p.x - c.x) * (p.x - c.x) + (p.y - c.y) * (p.y - c.y) + (p.z - c.z) * (p.z - c.z));
  }
  return {c, std::sqrt(r2)};
}

// The shape's bounds before its motion is applied.
BoundingSphere ObjectBounds(const Shape& shape) {
  switch (shape.type) {
    case Shape::Type::kSphere:
      return {shape.center, shape.radius};
    case Shape::Type::kQuad: {
      const Vec3& c = shape.corner;
      Vec3 u = shape.edgeU, v = shape.edgeV;
      return BoundsOf({c, {c.x + u.x, c.y + u.y, c.z + u.z},
                       {c.x + u.x + v.x, c.y + u.y + v.y, c.z + u.z + v.z},
                       {c.x + v.x, c.y + v.y, c.z + v.z}});
    }
    case Shape::Type::kMesh:
    case Shape::Type::kTerrain:
      return BoundsOf(shape.mesh.vertices);
  }
  return {};
}

bool SameVec(const AnimatedVec3& value, int a, int b) { return value.SameAt(a, b); }

// First frame in (frame, frame + window] at which `changed(f)` holds, else frame+window+1.
template <typename Changed>
int FirstChange(int frame, int window, Changed changed) {
  for (int f = frame + 1; f <= frame + window; ++f) {
    if (changed(f)) return f;
  }
  return frame + window + 1;
}

// Carries the running minimum through Embree's filter callback.
struct MeetingContext {
  RTCIntersectContext base;  // first member: Embree hands back a pointer to it
  const std::vector<int>* proxyHorizon;
  int earliest;
};

void RecordMeeting(const RTCFilterFunctionNArguments* args) {
  auto* context = reinterpret_cast<MeetingContext*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    unsigned primitive = RTCHitN_primID(args->hit, args->N, i);
    context->earliest = std::min(context->earliest, (*context->proxyHorizon)[primitive]);
    args->valid[i] = 0;  // keep traversing: a farther proxy may be of an earlier frame
  }
}

}  // namespace

HorizonOracle::HorizonOracle(const EmbreeDevice& device, const Scene& scene, int frame,
                             int window)
    : frame_(frame), window_(window), proxies_(rtcNewScene(device.get())) {
  const Camera& camera = scene.camera;
  cameraCap_ = FirstChange(frame, window, [&](int f) {
    return !SameVec(camera.position, frame, f) || !SameVec(camera.lookAt, frame, f);
  });
  lightCap_ = FirstChange(frame, window, [&](int f) {
    return std::any_of(scene.lights.begin(), scene.lights.end(), [&](const Light& light) {
      return !SameVec(light.position, frame, f) || !SameVec(light.direction, frame, f) ||
             !SameVec(light.intensity, frame, f);
    });
  });
  AddProxies(device, scene, std::min(frame + window, scene.render.LastFrame()));
  rtcCommitScene(proxies_.get());
  device.ThrowIfError("building horizon proxies");
  // A camera inside a proxy would start every segment inside it, unseen: be conservative.
  Vec3 eye = camera.position.Evaluate(frame);
  for (const Shape& shape : scene.shapes) {
    if (!shape.Moves()) continue;
    BoundingSphere b = ObjectBounds(shape);
    for (int f = frame; f <= std::min(frame + window, scene.render.LastFrame()); ++f) {
      Vec3 t = shape.translation.Evaluate(f);
      double dx = b.center.x + t.x - eye.x, dy = b.center.y + t.y - eye.y, dz = b.center.z + t.z - eye.z;
      double pad = kRelativeProxyPad * (std::fabs(eye.x) + std::fabs(eye.y) + std::fabs(eye.z) + b.radius);
      if (std::sqrt(dx * dx + dy * dy + dz * dz) <= b.radius + pad) {
        cameraCap_ = std::min(cameraCap_, std::max(f, frame + 1));
      }
    }
  }
}

void HorizonOracle::AddProxies(const EmbreeDevice& device, const Scene& scene, int lastFrame) {
  std::vector<float> points;  // x, y, z, radius per proxy
  for (const Shape& shape : scene.shapes) {
    if (!shape.Moves()) continue;
    BoundingSphere b = ObjectBounds(shape);
    for (int f = frame_; f <= lastFrame; ++f) {
      Vec3 t = shape.translation.Evaluate(f);
      Vec3 c{b.center.x + t.x, b.center.y + t.y, b.center.z + t.z};
      double magnitude = std::max({std::fabs(c.x), std::fabs(c.y), std::fabs(c.z)}) + b.radius;
      points.insert(points.end(), {static_cast<float>(c.x), static_cast<float>(c.y),
                                   static_cast<float>(c.z),
                                   static_cast<float>(b.radius + kRelativeProxyPad * magnitude)});
      proxyHorizon_.push_back(std::max(f, frame_ + 1));
    }
  }
  if (points.empty()) return;
  anyProxy_ = true;
  RTCGeometry geometry = rtcNewGeometry(device.get(), RTC_GEOMETRY_TYPE_SPHERE_POINT);
  size_t count = points.size() / 4;
  auto* buffer = static_cast<float*>(rtcSetNewGeometryBuffer(
      geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 4 * sizeof(float), count));
  std::copy(points.begin(), points.end(), buffer);
  rtcSetGeometryIntersectFilterFunction(geometry, RecordMeeting);
  rtcCommitGeometry(geometry);
  rtcAttachGeometry(proxies_.get(), geometry);
  rtcReleaseGeometry(geometry);
}

int HorizonOracle::FirstMeeting(const RaySegment& segment) const {
  if (!anyProxy_) return Unbounded();
  MeetingContext context;
  rtcInitIntersectContext(&context.base);
  context.proxyHorizon = &proxyHorizon_;
  context.earliest = Unbounded();
  RTCRayHit rayHit{};
  rayHit.ray.org_x = segment.origin.x, rayHit.ray.org_y = segment.origin.y;
  rayHit.ray.org_z = segment.origin.z;
  rayHit.ray.dir_x = segment.direction.x, rayHit.ray.dir_y = segment.direction.y;
  rayHit.ray.dir_z = segment.direction.z;
  rayHit.ray.tnear = 0;
  rayHit.ray.tfar = segment.length;
  rayHit.ray.mask = ~0u;
  rayHit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(proxies_.get(), &context.base, &rayHit);
  return context.earliest;
}

}  // namespace tcfarm
