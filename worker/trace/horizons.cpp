#include "trace/horizons.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "shapes/shape_kind.h"

namespace tcfarm {
namespace {

// Proxy radii grow by this fraction of the shape's coordinate magnitude: more than the
// tracer's relative ray offset (1e-5) and float rounding of hit points, so a segment that
// grazes a shape always meets its proxy.
constexpr double kRelativeProxyPad = 1e-4;

// First frame in (frame, frame + window] at which `changed(f)` holds, else frame+window+1.
template <typename Changed>
int FirstChange(int frame, int window, Changed changed) {
  for (int f = frame + 1; f <= frame + window; ++f) {
    if (changed(f)) return f;
  }
  return frame + window + 1;
}

// Whether any point of the segment lies within the sphere (center c, radius r).
bool SegmentMeetsSphere(const RaySegment& s, const float* sphere) {
  Float3 toCenter{sphere[0] - s.origin.x, sphere[1] - s.origin.y, sphere[2] - s.origin.z};
  float along = std::clamp(Dot(toCenter, s.direction), 0.0f, s.length);
  Float3 gap = toCenter - s.direction * along;
  return Dot(gap, gap) <= sphere[3] * sphere[3];
}

// Slabs are widened by this fraction of their distances against rounding: the cull may
// never say a false "no".
constexpr float kSlabSlack = 1e-4f;

// The segment with its direction's reciprocals, computed once for all its box tests.
struct SlabRay {
  float origin[3], inverse[3], length;
  explicit SlabRay(const RaySegment& s) : origin{s.origin.x, s.origin.y, s.origin.z}, length(s.length) {
    const float d[3] = {s.direction.x, s.direction.y, s.direction.z};
    // A huge finite reciprocal instead of infinity keeps 0 * inf (NaN) out of the slabs.
    for (int i = 0; i < 3; ++i) inverse[i] = d[i] == 0 ? 1e30f : 1.0f / d[i];
  }
};

bool Meets(const SlabRay& ray, const float lo[3], const float hi[3]) {
  float near = 0, far = ray.length;
  for (int axis = 0; axis < 3; ++axis) {
    float a = (lo[axis] - ray.origin[axis]) * ray.inverse[axis];
    float b = (hi[axis] - ray.origin[axis]) * ray.inverse[axis];
    float slack = kSlabSlack * (std::fabs(a) + std::fabs(b));
    near = std::max(near, std::min(a, b) - slack);
    far = std::min(far, std::max(a, b) + slack);
  }
  return near <= far;
}

// Meets() for every box of a one-array-per-coordinate layout at once, without branches,
// so that it vectorizes.
void BoxesMet(const SlabRay& ray, const std::vector<float> (&boxLo)[3], const std::vector<float> (&boxHi)[3],
              uint8_t* met) {
  const size_t lanes = boxLo[0].size();
  const float* lo[3] = {boxLo[0].data(), boxLo[1].data(), boxLo[2].data()};
  const float* hi[3] = {boxHi[0].data(), boxHi[1].data(), boxHi[2].data()};
  for (size_t i = 0; i < lanes; ++i) {
    float near = 0, far = ray.length;
    for (int axis = 0; axis < 3; ++axis) {
      const float a = (lo[axis][i] - ray.origin[axis]) * ray.inverse[axis];
      const float b = (hi[axis][i] - ray.origin[axis]) * ray.inverse[axis];
      const float slack = kSlabSlack * (std::fabs(a) + std::fabs(b));
      near = std::max(near, std::min(a, b) - slack);
      far = std::min(far, std::max(a, b) + slack);
    }
    met[i] = near <= far;
  }
}

}  // namespace

HorizonOracle::HorizonOracle(const Scene& scene, int frame, int window, const DeformedBounds& deformedBounds,
                             int walkFrames)
    : frame_(frame), window_(window),
      walkEnd_(walkFrames < 0 ? frame + window + 1 : std::min(frame + window + 1, frame + walkFrames + 1)),
      all_(EmptyBox()) {
  const Camera& camera = scene.camera;
  cameraCap_ = FirstChange(frame, window, [&](int f) {
    return !(camera.At(frame) == camera.At(f));
  });
  lightCap_ = FirstChange(frame, window, [&](int f) {
    return std::any_of(scene.lights.begin(), scene.lights.end(), [&](const Light& light) {
      return !light.SameAt(frame, f);
    });
  });
  int last = std::min(frame + window, scene.render.LastFrame());
  for (size_t i = 0; i < scene.shapes.size(); ++i) {
    const Shape& shape = scene.shapes[i];
    if (!shape.Moves()) continue;
    if (shape.Deforms()) {
      // Bounds of the posed vertices at each frame: a deforming mesh is a mover whose
      // proxies enclose every vertex it has at that frame.
      AddMover(shape, last, [&](int f) { return deformedBounds(i, f); });
    } else {
      const BoundingSphere rest = KindOf(shape).Bounds(shape);
      AddMover(shape, last, [&](int) { return rest; });
    }
  }
  std::vector<Box> swept;
  for (const Mover& mover : movers_) swept.push_back(mover.swept);
  LayBoxesOut(swept, sweptLo_, sweptHi_);
}

void HorizonOracle::LayBoxesOut(const std::vector<Box>& boxes, std::vector<float> (&lo)[3],
                                std::vector<float> (&hi)[3]) {
  const size_t lanes = (boxes.size() + kBoxLanes - 1) / kBoxLanes * kBoxLanes;
  for (int axis = 0; axis < 3; ++axis) {
    lo[axis].assign(lanes, INFINITY);
    hi[axis].assign(lanes, -INFINITY);
  }
  for (size_t i = 0; i < boxes.size(); ++i) {
    const float boxLo[3] = {boxes[i].lo.x, boxes[i].lo.y, boxes[i].lo.z};
    const float boxHi[3] = {boxes[i].hi.x, boxes[i].hi.y, boxes[i].hi.z};
    for (int axis = 0; axis < 3; ++axis) {
      lo[axis][i] = boxLo[axis];
      hi[axis][i] = boxHi[axis];
    }
  }
}

// The shape's bounding sphere placed at `frame`: its centre moved by the motion, its
// radius stretched by the motion's largest scale (rotation keeps lengths).
static BoundingSphere PlacedBounds(const Shape& shape, const BoundingSphere& object, int frame) {
  if (shape.motion.IsTranslationOnly()) {
    Vec3 t = shape.motion.translation.Evaluate(frame);
    return {{object.center.x + t.x, object.center.y + t.y, object.center.z + t.z}, object.radius};
  }
  const Affine worldFromObject = shape.motion.WorldFromObject(frame);
  return {worldFromObject.Apply(object.center), object.radius * worldFromObject.MaxStretch()};
}

void HorizonOracle::AddMover(const Shape& shape, int lastFrame,
                             const std::function<BoundingSphere(int frame)>& objectBounds) {
  Mover mover;
  mover.swept = EmptyBox();
  for (int f = frame_; f <= lastFrame; ++f) {
    const BoundingSphere placed = PlacedBounds(shape, objectBounds(f), f);
    const Vec3& c = placed.center;
    double magnitude = std::max({std::fabs(c.x), std::fabs(c.y), std::fabs(c.z)}) + placed.radius;
    // Padded, and rounded up again for the float conversion.
    double radius = (placed.radius + kRelativeProxyPad * magnitude) * (1 + 1e-6);
    mover.x.push_back(float(c.x));
    mover.y.push_back(float(c.y));
    mover.z.push_back(float(c.z));
    mover.radius.push_back(float(radius));
    float grow = float(radius) * (1 + 1e-5f) + 1e-6f * float(magnitude);
    size_t chunk = (f - frame_) / kFramesPerChunk;
    if (mover.chunks.size() <= chunk) mover.chunks.push_back(EmptyBox());
    for (Box* box : {&mover.swept, &mover.chunks.back(), &all_}) {
      box->lo = {std::min(box->lo.x, float(c.x) - grow), std::min(box->lo.y, float(c.y) - grow),
                 std::min(box->lo.z, float(c.z) - grow)};
      box->hi = {std::max(box->hi.x, float(c.x) + grow), std::max(box->hi.y, float(c.y) + grow),
                 std::max(box->hi.z, float(c.z) + grow)};
    }
  }
  mover.frames = mover.x.size();
  // Padding meets nothing: its radius is negative, and only lanes below `frames` are read.
  const size_t padded = mover.chunks.size() * kFramesPerChunk;
  mover.x.resize(padded, 0.0f);
  mover.y.resize(padded, 0.0f);
  mover.z.resize(padded, 0.0f);
  mover.radius.resize(padded, -1.0f);
  LayBoxesOut(mover.chunks, mover.chunkLo, mover.chunkHi);
  movers_.push_back(std::move(mover));
  // Only a sphere that merely translates is settled by arithmetic: a turned or scaled one
  // is placed through a float matrix whose rounding the margins were not made for, so its
  // blocked shadow rays are asked of Embree instead.
  if (shape.type != Shape::Type::kSphere || !shape.motion.IsTranslationOnly()) return;
  MovingSphere sphere{shape.radius, {}};
  for (int f = frame_; f <= lastFrame; ++f) {
    Vec3 t = shape.motion.translation.Evaluate(f);
    // In the tracer's own precision: a float centre placed by a float translation.
    sphere.centers.push_back({double(float(shape.center.x)) + double(float(t.x)),
                              double(float(shape.center.y)) + double(float(t.y)),
                              double(float(shape.center.z)) + double(float(t.z))});
  }
  spheres_.push_back(std::move(sphere));
}

bool HorizonOracle::SurelyBlocked(const RaySegment& segment, int frame, int* hint) const {
  if (frame <= frame_ || frame > frame_ + window_) return false;
  const int count = static_cast<int>(spheres_.size());
  if (*hint >= 0 && *hint < count && SphereSurelyBlocks(spheres_[*hint], segment, frame)) return true;
  for (int i = 0; i < count; ++i) {
    if (i != *hint && SphereSurelyBlocks(spheres_[i], segment, frame)) {
      *hint = i;
      return true;
    }
  }
  return false;
}

bool HorizonOracle::SphereSurelyBlocks(const MovingSphere& sphere, const RaySegment& segment,
                                       int frame) const {
  size_t index = static_cast<size_t>(frame - frame_);
  if (index >= sphere.centers.size()) return false;
  const Vec3& c = sphere.centers[index];
  const double ox = segment.origin.x, oy = segment.origin.y, oz = segment.origin.z;
  const double dx = segment.direction.x, dy = segment.direction.y, dz = segment.direction.z;
  const double length = segment.length;
  // Margins: the tracer rounds in float, relative to the coordinates' magnitude (~1e-7
  // of it per operation); these are a hundred times that and a thousandth of the radius.
  const double magnitude = std::max({std::fabs(c.x), std::fabs(c.y), std::fabs(c.z), std::fabs(ox),
                                     std::fabs(oy), std::fabs(oz)}) + sphere.radius;
  const double slack = 1e-3 * sphere.radius + 1e-5 * magnitude;
  const double inner = sphere.radius - slack, outer = sphere.radius + slack;
  if (inner <= 0) return false;
  const double ocx = c.x - ox, ocy = c.y - oy, ocz = c.z - oz;
  const double dd = dx * dx + dy * dy + dz * dz;
  const double along = (ocx * dx + ocy * dy + ocz * dz) / dd;
  const double px = ocx - along * dx, py = ocy - along * dy, pz = ocz - along * dz;
  const double missBy2 = px * px + py * py + pz * pz;
  if (missBy2 >= inner * inner) return false;  // not well inside
  if (ocx * ocx + ocy * ocy + ocz * ocz <= outer * outer) return false;  // starts inside
  if (std::isfinite(length)) {
    const double ex = ox + length * dx - c.x, ey = oy + length * dy - c.y, ez = oz + length * dz - c.z;
    if (ex * ex + ey * ey + ez * ez <= outer * outer) return false;  // ends inside
  }
  // Where the segment enters the inner sphere: well after its start, well before its end.
  const double enter = along - std::sqrt((inner * inner - missBy2) / dd);
  return enter > slack && enter < length - slack;
}

// SegmentMeetsSphere for the kFramesPerChunk proxies of a mover's chunk from `begin`,
// branch-free so that it vectorizes: bit i set when the proxy of frame offset begin + i
// meets the segment.
uint32_t HorizonOracle::ChunkSpheresMet(const RaySegment& s, const Mover& mover, size_t begin) {
  const float* x = mover.x.data() + begin;
  const float* y = mover.y.data() + begin;
  const float* z = mover.z.data() + begin;
  const float* r = mover.radius.data() + begin;
  int32_t met[kFramesPerChunk];
  for (size_t i = 0; i < kFramesPerChunk; ++i) {
    const float tx = x[i] - s.origin.x, ty = y[i] - s.origin.y, tz = z[i] - s.origin.z;
    const float along = std::min(std::max(tx * s.direction.x + ty * s.direction.y + tz * s.direction.z, 0.0f),
                                 s.length);
    const float gx = tx - s.direction.x * along, gy = ty - s.direction.y * along, gz = tz - s.direction.z * along;
    met[i] = (gx * gx + gy * gy + gz * gz <= r[i] * r[i]) && r[i] >= 0 ? 1 : 0;
  }
  uint32_t bits = 0;
  for (size_t i = 0; i < kFramesPerChunk; ++i) bits |= static_cast<uint32_t>(met[i]) << i;
  return bits;
}

// Bits of a chunk starting at frame offset `chunkBegin` for the offsets [from, to).
uint32_t HorizonOracle::LaneMask(size_t chunkBegin, size_t from, size_t to) {
  uint32_t mask = 0;
  for (size_t i = from; i < to; ++i) mask |= 1u << (i - chunkBegin);
  return mask;
}

HorizonOracle::Box HorizonOracle::EmptyBox() {
  return {{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}};
}

int HorizonOracle::FirstMeeting(const RaySegment& segment, int before) const {
  before = std::min(before, Unbounded());
  if (movers_.empty() || before <= frame_ + 1) return before;
  const SlabRay ray(segment);
  {
    const float lo[3] = {all_.lo.x, all_.lo.y, all_.lo.z}, hi[3] = {all_.hi.x, all_.hi.y, all_.hi.z};
    if (!Meets(ray, lo, hi)) return before;
  }
  // Bytes of box tests: on the stack for the usual few movers and chunks.
  constexpr size_t kStackLanes = 256;
  uint8_t stackNear[kStackLanes], stackChunks[kStackLanes];
  thread_local std::vector<uint8_t> heapNear, heapChunks;
  auto scratch = [](size_t lanes, uint8_t* stack, std::vector<uint8_t>& heap) {
    if (lanes <= kStackLanes) return stack;
    heap.resize(lanes);
    return heap.data();
  };
  uint8_t* near = scratch(sweptLo_[0].size(), stackNear, heapNear);
  BoxesMet(ray, sweptLo_, sweptHi_, near);
  // Mover by mover, the first chunk its path meets the segment in, then the first frame in
  // it: each mover is searched only before the earliest meeting found so far.
  size_t earliest = static_cast<size_t>(before - frame_);  // as a frame offset; none found yet
  for (size_t m = 0; m < movers_.size(); ++m) {
    if (!near[m]) continue;
    const Mover& mover = movers_[m];
    uint8_t* chunkMet = scratch(mover.chunkLo[0].size(), stackChunks, heapChunks);
    BoxesMet(ray, mover.chunkLo, mover.chunkHi, chunkMet);
    for (size_t chunk = 0; chunk < mover.chunks.size() && chunk * kFramesPerChunk < earliest; ++chunk) {
      if (!chunkMet[chunk]) continue;
      const size_t begin = chunk * kFramesPerChunk;
      const size_t end = std::min(earliest, mover.frames);
      const uint32_t met = ChunkSpheresMet(segment, mover, begin) & LaneMask(begin, std::max<size_t>(begin, 1), end);
      if (met != 0) {
        earliest = begin + static_cast<size_t>(__builtin_ctz(met));
        break;
      }
    }
  }
  return std::min(before, frame_ + static_cast<int>(earliest));
}

bool HorizonOracle::MayBeBlockedByMover(const RaySegment& segment) const {
  return std::any_of(movers_.begin(), movers_.end(), [&](const Mover& mover) {
    const float sphere[4] = {mover.x[0], mover.y[0], mover.z[0], mover.radius[0]};  // its bounds at frame()
    return SegmentMeetsSphere(segment, sphere);
  });
}

}  // namespace tcfarm
