#include "worker/trace/horizons.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <stdexcept>

#include "worker/shapes/shape_kind.h"
#include "worker/trace/lights.h"
#include "worker/trace/ray_offset.h"
#include "worker/trace/segment_fan.h"

namespace tcfarm {
namespace {

// Proxy radii grow by this fraction of the shape's coordinate magnitude: more than the
// tracer's relative ray offset (1e-5) and float rounding of hit points, so a segment that
// grazes a shape always meets its proxy.
constexpr double kRelativeProxyPad = 1e-4;

// The first frame in (frame, lastFrame] at which `changed(f)` holds, else `none`.
template <typename Changed>
int FirstChange(int frame, int lastFrame, int none, Changed changed) {
  for (int f = frame + 1; f <= lastFrame; ++f) {
    if (changed(f)) return f;
  }
  return none;
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

HorizonOracle::HorizonOracle(const Scene& scene, int frame, int window, const DeformingMeshes& deforming,
                             int walkFrames)
    : frame_(frame), window_(window),
      walkEnd_(walkFrames < 0 ? frame + window + 1 : std::min(frame + window + 1, frame + walkFrames + 1)),
      all_(EmptyBox()) {
  const Camera& camera = scene.camera;
  cameraCap_ = FirstChange(frame, frame + window, Unbounded(), [&](int f) {
    return !(camera.At(frame) == camera.At(f));
  });
  lightCap_ = FirstChange(frame, frame + window, Unbounded(), [&](int f) {
    return std::any_of(scene.lights.begin(), scene.lights.end(), [&](const Light& light) {
      return !light.SameAt(frame, f);
    });
  });
  int last = std::min(frame + window, scene.render.LastFrame());
  wholeChange_.assign(scene.shapes.size(), Unbounded());
  sphereOfShape_.assign(scene.shapes.size(), -1);
  partChanges_.resize(scene.shapes.size());
  for (size_t i = 0; i < scene.shapes.size(); ++i) {
    const Shape& shape = scene.shapes[i];
    if (!shape.Moves()) continue;
    if (shape.Deforms()) {
      AddDeformingMesh(shape, i, last, *deforming(i));
    } else {
      AddRigidShape(shape, i, last);
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

namespace {

// A proxy as the tests read it: the placed bounds padded beyond the tracer's rounding.
struct Proxy {
  float x, y, z, radius;
  float grow;  // what boxes around it add on each side
};

Proxy Padded(const BoundingSphere& placed) {
  const Vec3& c = placed.center;
  double magnitude = std::max({std::fabs(c.x), std::fabs(c.y), std::fabs(c.z)}) + placed.radius;
  // Padded, and rounded up again for the float conversion.
  double radius = (placed.radius + kRelativeProxyPad * magnitude) * (1 + 1e-6);
  return {float(c.x), float(c.y), float(c.z), float(radius), float(radius) * (1 + 1e-5f) + 1e-6f * float(magnitude)};
}

// The bounding sphere of spheres: around their box's centre; a negative radius for none.
BoundingSphere Union(const std::vector<BoundingSphere>& spheres) {
  if (spheres.empty()) return {{}, -1};
  Vec3 lo{INFINITY, INFINITY, INFINITY}, hi{-INFINITY, -INFINITY, -INFINITY};
  for (const BoundingSphere& s : spheres) {
    for (int axis = 0; axis < 3; ++axis) {
      lo[axis] = std::min(lo[axis], s.center[axis] - s.radius);
      hi[axis] = std::max(hi[axis], s.center[axis] + s.radius);
    }
  }
  const Vec3 center{(lo.x + hi.x) / 2, (lo.y + hi.y) / 2, (lo.z + hi.z) / 2};
  double radius = 0;
  for (const BoundingSphere& s : spheres) {
    const double dx = s.center.x - center.x, dy = s.center.y - center.y, dz = s.center.z - center.z;
    radius = std::max(radius, std::sqrt(dx * dx + dy * dy + dz * dz) + s.radius);
  }
  return {center, radius * (1 + 1e-12)};
}

}  // namespace

namespace {

constexpr BoundingSphere kNoBounds{{}, -1};

}  // namespace

void HorizonOracle::AddRigidShape(const Shape& shape, size_t index, int lastFrame) {
  // A shape placed at f by the same transform as at frame() is where the trace saw it, to
  // the bit: a pause in its motion changes nothing.
  const Affine atFrame = shape.motion.WorldFromObject(frame_);
  auto placedAsAtFrame = [&](int f) { return shape.motion.WorldFromObject(f) == atFrame; };
  wholeChange_[index] = FirstChange(frame_, lastFrame, Unbounded(), [&](int f) { return !placedAsAtFrame(f); });
  const BoundingSphere rest = KindOf(shape).Bounds(shape);
  // Its bounds at frame() itself are what may block a shadow ray there (MoverThatMayBlock).
  AddMover(shape, lastFrame, [&](int f) { return placedAsAtFrame(f) ? kNoBounds : rest; }, rest);
  sphereOfShape_[index] = sphereOfMover_.back();
}

void HorizonOracle::AddDeformingMesh(const Shape& shape, size_t index, int lastFrame, DeformingMesh& mesh) {
  const std::shared_ptr<const DeformingMesh::PoseKey> base = mesh.KeyOf(frame_);
  if (shape.motion.IsAnimated()) {
    // Placed as a whole too: every part may move, at every frame it is placed or posed
    // otherwise than at frame().
    const Affine atFrame = shape.motion.WorldFromObject(frame_);
    auto asAtFrame = [&](int f) { return shape.motion.WorldFromObject(f) == atFrame && *mesh.KeyOf(f) == *base; };
    wholeChange_[index] = FirstChange(frame_, lastFrame, Unbounded(), [&](int f) { return !asAtFrame(f); });
    // Its bounds at frame() itself are what may block a shadow ray there (MoverThatMayBlock).
    const BoundingSphere bounds = Union(mesh.PartBoundsAt(frame_)->groups);
    std::vector<BoundingSphere> pieces;  // every part's, read by AddMover before the next frame's
    AddMover(
        shape, lastFrame, [&](int f) { return asAtFrame(f) ? kNoBounds : Union(mesh.PartBoundsAt(f)->groups); },
        bounds, [&](int f) -> const std::vector<BoundingSphere>& {
          pieces.clear();
          for (const std::vector<BoundingSphere>& ofPart : mesh.PartBoundsAt(f)->pieces) {
            pieces.insert(pieces.end(), ofPart.begin(), ofPart.end());
          }
          return pieces;
        });
    return;
  }
  const DeformationParts& parts = mesh.Parts();
  // Per part, per frame from frame() on: whether it is posed otherwise than at frame(),
  // which its joints' matrices and its targets' weights say.
  const size_t frames = static_cast<size_t>(lastFrame - frame_) + 1;
  std::vector<std::vector<uint8_t>> moved(parts.groups.size(), std::vector<uint8_t>(frames, 0));
  std::vector<uint8_t> jointMoved(base->skinMatrices.size()), targetMoved(base->morphWeights.size());
  for (int f = frame_ + 1; f <= lastFrame; ++f) {
    const std::shared_ptr<const DeformingMesh::PoseKey> key = mesh.KeyOf(f);
    for (size_t j = 0; j < jointMoved.size(); ++j) jointMoved[j] = !(key->skinMatrices[j] == base->skinMatrices[j]);
    for (size_t t = 0; t < targetMoved.size(); ++t) targetMoved[t] = key->morphWeights[t] != base->morphWeights[t];
    for (size_t g = 0; g < parts.groups.size(); ++g) {
      const DeformationParts::Group& group = parts.groups[g];
      moved[g][static_cast<size_t>(f - frame_)] =
          std::any_of(group.joints.begin(), group.joints.end(), [&](uint32_t j) { return jointMoved[j]; }) ||
          std::any_of(group.targets.begin(), group.targets.end(), [&](uint32_t t) { return targetMoved[t]; });
    }
  }
  PartChanges& changes = partChanges_[index];
  changes.parts = &parts;
  changes.mesh = &shape.Mesh();
  const std::shared_ptr<const DeformingMesh::PartBounds> atFrame = mesh.PartBoundsAt(frame_);
  for (size_t g = 0; g < parts.groups.size(); ++g) {
    const std::vector<uint8_t>& partMoved = moved[g];
    changes.groupChange.push_back(
        FirstChange(frame_, lastFrame, Unbounded(), [&](int f) { return partMoved[size_t(f - frame_)] != 0; }));
    if (changes.groupChange.back() == Unbounded()) continue;  // holds still: no mover
    // Each part is a mover of its own, bounded by its own vertices: the union of a
    // character's parts is a sphere around the whole body, which most of the rays near
    // it meet though few pass a part that moves.
    // The memo keeps every frame's bounds, so the pieces outlive the call.
    AddMover(
        shape, lastFrame, [&](int f) { return partMoved[size_t(f - frame_)] ? mesh.PartBoundsAt(f)->groups[g] : kNoBounds; },
        atFrame->groups[g], [&](int f) -> const std::vector<BoundingSphere>& { return mesh.PartBoundsAt(f)->pieces[g]; });
  }
}

int HorizonOracle::SurfaceChange(int shape, uint32_t primitive) const {
  const PartChanges& changes = partChanges_[static_cast<size_t>(shape)];
  if (changes.groupChange.empty()) return wholeChange_[static_cast<size_t>(shape)];
  int change = Unbounded();
  for (uint32_t corner : changes.mesh->triangles[primitive]) {
    change = std::min(change, changes.groupChange[changes.parts->groupOfVertex[corner]]);
  }
  return change;
}

// Spheres' proxies at a frame appended as four arrays of `lanes` floats (x, y, z,
// radius), a negative radius for none and for the padding.
static void AppendProxies(const Shape& shape, const std::vector<BoundingSphere>* objects, int frame, size_t lanes,
                          std::vector<float>& out) {
  const size_t at = out.size();
  out.resize(at + 4 * lanes, 0.0f);
  std::fill(out.begin() + static_cast<std::ptrdiff_t>(at + 3 * lanes), out.end(), -1.0f);
  for (size_t i = 0; objects && i < objects->size(); ++i) {
    if ((*objects)[i].radius < 0) continue;
    const Proxy proxy = Padded(PlacedBounds(shape, (*objects)[i], frame));
    out[at + i] = proxy.x, out[at + lanes + i] = proxy.y, out[at + 2 * lanes + i] = proxy.z;
    out[at + 3 * lanes + i] = proxy.radius;
  }
}

void HorizonOracle::AddMover(const Shape& shape, int lastFrame,
                             const std::function<BoundingSphere(int frame)>& objectBounds,
                             const BoundingSphere& atFrame, const PiecesAt& objectPieces) {
  Mover mover;
  mover.swept = EmptyBox();
  {
    const Proxy at = Padded(PlacedBounds(shape, atFrame, frame_));
    mover.atFrame[0] = at.x, mover.atFrame[1] = at.y, mover.atFrame[2] = at.z;
    mover.atFrame[3] = atFrame.radius >= 0 ? at.radius : -1.0f;
  }
  size_t pieceCount = 0;
  // One piece is the whole again: nothing to ask beyond the proxy.
  if (objectPieces && objectPieces(frame_).size() > 1) {
    const std::vector<BoundingSphere>& pieces = objectPieces(frame_);
    pieceCount = pieces.size();
    mover.pieceLanes = (pieceCount + kBoxLanes - 1) / kBoxLanes * kBoxLanes;
    AppendProxies(shape, &pieces, frame_, mover.pieceLanes, mover.atFramePieces);
  }
  for (int f = frame_; f <= lastFrame; ++f) {
    const BoundingSphere object = objectBounds(f);
    size_t chunk = (f - frame_) / kFramesPerChunk;
    if (mover.chunks.size() <= chunk) mover.chunks.push_back(EmptyBox());
    if (object.radius < 0) {  // nothing of it changed by f: meets nothing
      mover.x.push_back(0), mover.y.push_back(0), mover.z.push_back(0), mover.radius.push_back(-1);
      if (mover.pieceLanes > 0) AppendProxies(shape, nullptr, f, mover.pieceLanes, mover.pieces);
      continue;
    }
    if (mover.pieceLanes > 0) {
      const std::vector<BoundingSphere>& pieces = objectPieces(f);
      if (pieces.size() != pieceCount) throw std::logic_error("a mover's pieces changed in number");
      AppendProxies(shape, &pieces, f, mover.pieceLanes, mover.pieces);
    }
    const Proxy proxy = Padded(PlacedBounds(shape, object, f));
    mover.x.push_back(proxy.x);
    mover.y.push_back(proxy.y);
    mover.z.push_back(proxy.z);
    mover.radius.push_back(proxy.radius);
    const float grow = proxy.grow;
    for (Box* box : {&mover.swept, &mover.chunks.back(), &all_}) {
      box->lo = {std::min(box->lo.x, proxy.x - grow), std::min(box->lo.y, proxy.y - grow),
                 std::min(box->lo.z, proxy.z - grow)};
      box->hi = {std::max(box->hi.x, proxy.x + grow), std::max(box->hi.y, proxy.y + grow),
                 std::max(box->hi.z, proxy.z + grow)};
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
  sphereOfMover_.push_back(-1);
  // Only a sphere that merely translates is settled by arithmetic: a turned or scaled one
  // is placed through a float matrix whose rounding the margins were not made for, so its
  // blocked shadow rays are asked of Embree instead.
  if (shape.type != Shape::Type::kSphere || !shape.motion.IsTranslationOnly()) return;
  sphereOfMover_.back() = static_cast<int>(spheres_.size());
  MovingSphere sphere{shape.radius, {}, 0, movers_.size() - 1};
  for (int f = frame_; f <= lastFrame; ++f) {
    Vec3 t = shape.motion.translation.Evaluate(f);
    // In the tracer's own precision: a float centre placed by a float translation.
    sphere.centers.push_back({double(float(shape.center.x)) + double(float(t.x)),
                              double(float(shape.center.y)) + double(float(t.y)),
                              double(float(shape.center.z)) + double(float(t.z))});
  }
  for (size_t i = 1; i < sphere.centers.size(); ++i) {
    const Vec3& a = sphere.centers[i - 1];
    const Vec3& b = sphere.centers[i];
    sphere.step = std::max(sphere.step, std::sqrt((b.x - a.x) * (b.x - a.x) + (b.y - a.y) * (b.y - a.y) +
                                                  (b.z - a.z) * (b.z - a.z)));
  }
  spheres_.push_back(std::move(sphere));
}

namespace {

// A blocked shadow ray in double, with what each frame's test against a sphere needs of
// it computed once.
struct BlockedRay {
  double ox, oy, oz, dx, dy, dz;
  double dd, length;
  double ex, ey, ez;  // its end, when finite
  bool finite;
  double originMagnitude;
  explicit BlockedRay(const RaySegment& s)
      : ox(s.origin.x), oy(s.origin.y), oz(s.origin.z),
        dx(s.direction.x), dy(s.direction.y), dz(s.direction.z),
        dd(dx * dx + dy * dy + dz * dz), length(s.length),
        ex(ox + length * dx), ey(oy + length * dy), ez(oz + length * dz),
        finite(std::isfinite(s.length)),
        originMagnitude(std::max({std::fabs(ox), std::fabs(oy), std::fabs(oz)})) {}
};

// The squared distance from the sphere's centre to the ray's line.
double MissBy2(const BlockedRay& ray, const Vec3& c) {
  const double ocx = c.x - ray.ox, ocy = c.y - ray.oy, ocz = c.z - ray.oz;
  const double along = (ocx * ray.dx + ocy * ray.dy + ocz * ray.dz) / ray.dd;
  const double px = ocx - along * ray.dx, py = ocy - along * ray.dy, pz = ocz - along * ray.dz;
  return px * px + py * py + pz * pz;
}

// What the test of a ray against a sphere at one frame says of the frames after it, given
// that the sphere's centre moves at most `step` a frame: every distance the test compares
// moves by at most that much a frame, and the margins (grown by the centre's magnitude)
// by 1e-5 of it.
struct SureBlock {
  bool blocked = false;
  int keeps = 0;     // frames after this one it surely still blocks the ray
  int endsHold = 0;  // frames after this one all but how far the ray passes from the
                     // centre surely still hold: only that needs testing there
  double inner = 0;  // the radius the ray must pass within, at this frame
};

// The margin of the arithmetic tests against a sphere of `radius` whose centre and ray
// reach coordinates of `magnitude`: the tracer rounds in float, relative to the
// coordinates' magnitude (~1e-7 of it per operation); this is a hundred times that, and a
// thousandth of the radius.
double SureSlack(double magnitude, double radius) { return 1e-3 * radius + 1e-5 * (magnitude + radius); }

// Whether the sphere surely blocks the ray: it runs through the sphere well inside, from
// outside to outside, with margins far above the rounding of the tracer's own ray-sphere
// test, so that test says "blocked" too.
SureBlock TestSureBlock(const BlockedRay& ray, const Vec3& c, double radius, double step) {
  const double slack = SureSlack(std::max({std::fabs(c.x), std::fabs(c.y), std::fabs(c.z), ray.originMagnitude}), radius);
  const double inner = radius - slack, outer = radius + slack;
  if (inner <= 0) return {};
  const double ocx = c.x - ray.ox, ocy = c.y - ray.oy, ocz = c.z - ray.oz;
  const double along = (ocx * ray.dx + ocy * ray.dy + ocz * ray.dz) / ray.dd;
  const double px = ocx - along * ray.dx, py = ocy - along * ray.dy, pz = ocz - along * ray.dz;
  const double missBy2 = px * px + py * py + pz * pz;
  if (missBy2 >= inner * inner) return {};  // not well inside
  const double startBy2 = ocx * ocx + ocy * ocy + ocz * ocz;
  if (startBy2 <= outer * outer) return {};  // starts inside
  double endBy2 = INFINITY;
  if (ray.finite) {
    const double ex = ray.ex - c.x, ey = ray.ey - c.y, ez = ray.ez - c.z;
    endBy2 = ex * ex + ey * ey + ez * ez;
    if (endBy2 <= outer * outer) return {};  // ends inside
  }
  // Where the segment enters the inner sphere: well after its start, well before its end.
  const double enter = along - std::sqrt((inner * inner - missBy2) / ray.dd);
  if (!(enter > slack && enter < ray.length - slack)) return {};
  // With both ends outside, the ray runs through while its closest approach stays inside
  // and between its ends (then it enters at least 2 * slack from either end).
  const double ends = std::min({std::sqrt(startBy2) - outer, std::sqrt(endBy2) - outer, along, ray.length - along});
  const double perFrame = step * (1 + 1e-5) + 1e-300;
  auto frames = [&](double margin) { return static_cast<int>(std::min(1e6, std::floor(margin / perFrame * (1 - 1e-9)))); };
  return {true, frames(std::min(ends, inner - std::sqrt(missBy2))), frames(ends), inner};
}

}  // namespace

int HorizonOracle::FirstNotSurelyBlocked(const RaySegment& segment, int from, int before, int* hint) const {
  const int count = static_cast<int>(spheres_.size());
  before = std::min(before, frame_ + window_ + 1);
  int frame = std::max(from, frame_ + 1);
  if (count == 0) return std::min(frame, before);
  const BlockedRay ray(segment);
  // Only spheres whose path over the window comes near the ray can block it; found when
  // the blocker found last lets go, which many rays never reach within their horizon.
  uint8_t nearStack[256];
  thread_local std::vector<uint8_t> nearHeap;
  uint8_t* near = nullptr;
  auto nearSpheres = [&] {
    if (near) return near;
    near = nearStack;
    if (sweptLo_[0].size() > 256) nearHeap.resize(sweptLo_[0].size()), near = nearHeap.data();
    BoxesMet(SlabRay(segment), sweptLo_, sweptHi_, near);
    return near;
  };
  auto test = [&](int sphere, int f) {
    const MovingSphere& s = spheres_[static_cast<size_t>(sphere)];
    const size_t index = static_cast<size_t>(f - frame_);
    if (index >= s.centers.size()) return SureBlock{};
    SureBlock sure = TestSureBlock(ray, s.centers[index], s.radius, s.step);
    const int left = static_cast<int>(s.centers.size() - 1 - index);  // frames it has after f
    sure.keeps = std::min(sure.keeps, left), sure.endsHold = std::min(sure.endsHold, left);
    return sure;
  };
  // From a frame the blocker surely blocks the ray at, on: first the frames its margins
  // cover, then, while the ray's ends surely stay clear, only how far the ray passes from
  // the centre, against the least inner radius those frames can have.
  auto follow = [&](int sphere) {
    for (SureBlock sure; frame < before && (sure = test(sphere, frame)).blocked;) {
      const int first = frame;
      const int last = std::min(before - 1, first + sure.endsHold);
      frame += 1 + sure.keeps;
      const MovingSphere& s = spheres_[static_cast<size_t>(sphere)];
      const double inner = sure.inner - 1e-5 * s.step * (1 + 1e-5) * (last - first);
      while (inner > 0 && frame <= last && MissBy2(ray, s.centers[static_cast<size_t>(frame - frame_)]) < inner * inner) {
        ++frame;
      }
    }
  };
  while (frame < before) {
    if (*hint >= 0 && *hint < count) {
      follow(*hint);
      if (frame >= before) break;
    }
    int other = 0;
    const uint8_t* nearby = nearSpheres();
    while (other < count && (other == *hint || !nearby[spheres_[static_cast<size_t>(other)].mover] ||
                             !test(other, frame).blocked)) {
      ++other;
    }
    if (other == count) return frame;
    *hint = other;
  }
  return before;
}

// SegmentMeetsSphere without branches, 1 or 0, for loops the compiler turns into SIMD;
// a negative radius meets nothing.
static inline int32_t SphereMet(const RaySegment& s, float x, float y, float z, float r) {
  const float tx = x - s.origin.x, ty = y - s.origin.y, tz = z - s.origin.z;
  const float along = std::min(std::max(tx * s.direction.x + ty * s.direction.y + tz * s.direction.z, 0.0f), s.length);
  const float gx = tx - s.direction.x * along, gy = ty - s.direction.y * along, gz = tz - s.direction.z * along;
  return (gx * gx + gy * gy + gz * gz <= r * r) & (r >= 0);
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
  for (size_t i = 0; i < kFramesPerChunk; ++i) met[i] = SphereMet(s, x[i], y[i], z[i], r[i]);
  uint32_t bits = 0;
  for (size_t i = 0; i < kFramesPerChunk; ++i) bits |= static_cast<uint32_t>(met[i]) << i;
  return bits;
}

// SphereMet for `lanes` spheres laid out as four arrays (AppendProxies).
static bool AnyPieceMet(const RaySegment& s, const float* pieces, size_t lanes) {
  const float* x = pieces;
  const float* y = pieces + lanes;
  const float* z = pieces + 2 * lanes;
  const float* r = pieces + 3 * lanes;
  int32_t met = 0;
  for (size_t i = 0; i < lanes; ++i) met |= SphereMet(s, x[i], y[i], z[i], r[i]);
  return met != 0;
}

bool HorizonOracle::PiecesMet(const RaySegment& segment, const Mover& mover, size_t offset) {
  if (mover.pieceLanes == 0) return true;
  return AnyPieceMet(segment, mover.pieces.data() + offset * 4 * mover.pieceLanes, mover.pieceLanes);
}

bool HorizonOracle::PiecesMetAtFrame(const RaySegment& segment, const Mover& mover) {
  return mover.pieceLanes == 0 || AnyPieceMet(segment, mover.atFramePieces.data(), mover.pieceLanes);
}

// Bits of a chunk starting at frame offset `chunkBegin` for the offsets [from, to).
uint32_t HorizonOracle::LaneMask(size_t chunkBegin, size_t from, size_t to) {
  to = std::min(to, chunkBegin + kFramesPerChunk);  // a shift past the mask's width is undefined
  uint32_t mask = 0;
  for (size_t i = from; i < to; ++i) mask |= 1u << (i - chunkBegin);
  return mask;
}

HorizonOracle::Box HorizonOracle::EmptyBox() {
  return {{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}};
}

int HorizonOracle::FirstMeeting(const RaySegment& segment, int before, int exceptMover) const {
  before = std::min(before, Unbounded());
  if (movers_.empty() || before <= frame_ + 1 || !NearAnyMover(segment)) return before;
  const SlabRay ray(segment);
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
    if (!near[m] || static_cast<int>(m) == exceptMover) continue;
    const Mover& mover = movers_[m];
    uint8_t* chunkMet = scratch(mover.chunkLo[0].size(), stackChunks, heapChunks);
    BoxesMet(ray, mover.chunkLo, mover.chunkHi, chunkMet);
    for (size_t chunk = 0; chunk < mover.chunks.size() && chunk * kFramesPerChunk < earliest; ++chunk) {
      if (!chunkMet[chunk]) continue;
      const size_t begin = chunk * kFramesPerChunk;
      const size_t end = std::min({earliest, mover.frames, begin + kFramesPerChunk});
      uint32_t met = ChunkSpheresMet(segment, mover, begin) & LaneMask(begin, std::max<size_t>(begin, 1), end);
      for (; met != 0; met &= met - 1) {  // frames whose proxy it meets, the first one first
        const size_t offset = begin + static_cast<size_t>(__builtin_ctz(met));
        if (PiecesMet(segment, mover, offset)) {
          earliest = offset;
          break;
        }
      }
      if (earliest < end) break;
    }
  }
  return std::min(before, frame_ + static_cast<int>(earliest));
}

bool HorizonOracle::NearAnyMover(const RaySegment& segment) const {
  const float lo[3] = {all_.lo.x, all_.lo.y, all_.lo.z}, hi[3] = {all_.hi.x, all_.hi.y, all_.hi.z};
  return Meets(SlabRay(segment), lo, hi);
}

HorizonOracle::MoverSphere HorizonOracle::MoverAt(size_t mover, size_t offset) const {
  const Mover& m = movers_[mover];
  if (offset >= m.frames) return {0, 0, 0, -1};
  return {m.x[offset], m.y[offset], m.z[offset], m.radius[offset]};
}

double HorizonOracle::FanSlack(const Vec3& point) const {
  double magnitude = std::max({std::fabs(point.x), std::fabs(point.y), std::fabs(point.z)});
  if (all_.lo.x <= all_.hi.x) {  // some proxy
    magnitude = std::max({magnitude, double(MaxAbsComponent(all_.lo)), double(MaxAbsComponent(all_.hi))});
  }
  // Shadow rays start off their surface by the tracer's ray offset (1e-5 of the hit's
  // magnitude, camera distance included) while they aim at the light from the surface
  // itself, so their lines miss the light by up to that offset: a hundred times it.
  return 1e-3 * (1 + magnitude);
}

void HorizonOracle::FanFirstMeetings(const SegmentFan& fan, int32_t* horizon, const int32_t* exceptMover) const {
  if (fan.empty() || movers_.empty()) return;
  FanCones& cones = *fan.cones();
  const size_t frames = cones.Frames();
  std::array<const FaceRect*, 6> conesOn{}, spansOn{};
  for (int face : fan.Faces()) conesOn[face] = cones.Cones(face), spansOn[face] = cones.SpanCones(face);
  // Frames at or beyond every sample's horizon cannot lower any.
  int latest = frame_ + 1;
  fan.ForEach([&](const SegmentFan::Entry& entry) { latest = std::max(latest, int(horizon[entry.sample])); });
  // Per mover, whether its cones over the current span of frames miss the fan's segments.
  thread_local std::vector<uint8_t> passedBy;
  passedBy.assign(movers_.size(), 0);
  for (int frame = frame_ + 1; frame < latest; ++frame) {
    const size_t offset = static_cast<size_t>(frame - frame_);
    if ((offset - 1) % FanCones::kSpan == 0) {
      const size_t span = (offset - 1) / FanCones::kSpan;
      for (size_t m = 0; m < movers_.size(); ++m) {
        passedBy[m] = std::none_of(fan.Faces().begin(), fan.Faces().end(), [&](int face) {
          return fan.Overlaps(face, spansOn[face][m * cones.Spans() + span]);
        });
      }
    }
    for (size_t m = 0; m < movers_.size(); ++m) {
      const Mover& mover = movers_[m];
      if (passedBy[m] || offset >= mover.frames || mover.radius[offset] < 0) continue;
      const float sphere[4] = {mover.x[offset], mover.y[offset], mover.z[offset], mover.radius[offset]};
      for (int face : fan.Faces()) {
        fan.ForEachIn(face, conesOn[face][m * frames + offset], [&](const SegmentFan::Entry& entry) {
          int32_t& h = horizon[entry.sample];
          if (h > frame && SegmentMeetsSphere(entry.segment, sphere) &&
              !(exceptMover && exceptMover[entry.sample] == static_cast<int32_t>(m)) &&
              PiecesMet(entry.segment, mover, offset)) {
            h = frame;
          }
        });
      }
    }
  }
}

int HorizonOracle::MoverThatMayBlock(const RaySegment& segment, int exceptMover) const {
  for (size_t m = 0; m < movers_.size(); ++m) {
    if (static_cast<int>(m) == exceptMover || movers_[m].atFrame[3] < 0) continue;
    if (SegmentMeetsSphere(segment, movers_[m].atFrame) && PiecesMetAtFrame(segment, movers_[m])) {
      return static_cast<int>(m);
    }
  }
  return -1;
}

int HorizonOracle::SphereOfMover(int mover) const { return sphereOfMover_[static_cast<size_t>(mover)]; }

namespace {

// A camera ray against a translating sphere at one frame, in double.
struct RayAgainstSphere {
  double along;     // distance along the ray to the point nearest the centre
  double missBy2;   // squared distance from the centre to the ray's line
  double startBy2;  // squared distance from the centre to the ray's origin
  RayAgainstSphere(const Vec3& o, const Vec3& d, const Vec3& c) {
    const Vec3 oc = SubtractD(c, o);
    along = DotD(oc, d);
    startBy2 = DotD(oc, oc);
    missBy2 = std::max(0.0, startBy2 - along * along);
  }
};

double MaxAbs(const Vec3& v) { return std::max({std::fabs(v.x), std::fabs(v.y), std::fabs(v.z)}); }

}  // namespace

int HorizonOracle::UnlitSphereHolds(int sphere, const RaySegment& hit, const std::vector<ShadingLight>& lights,
                                    const int* blockers, int before) const {
  const MovingSphere& s = spheres_[static_cast<size_t>(sphere)];
  const Vec3 o{hit.origin.x, hit.origin.y, hit.origin.z};
  const Vec3 d = NormalizeD({hit.direction.x, hit.direction.y, hit.direction.z});
  before = std::min(before, Unbounded());
  for (int frame = frame_ + 1; frame < before; ++frame) {
    const size_t index = static_cast<size_t>(frame - frame_);
    if (index >= s.centers.size()) return frame;
    const Vec3& c = s.centers[index];
    const double slack = SureSlack(std::max(MaxAbs(c), MaxAbs(o)), s.radius);
    const double inner = s.radius - slack, outer = s.radius + slack;
    const RayAgainstSphere at(o, d, c);
    // From outside, well inside the rim, and well before the hit at frame().
    if (at.startBy2 <= outer * outer || at.missBy2 >= inner * inner) return frame;
    const double t = at.along - std::sqrt(s.radius * s.radius - at.missBy2);
    if (!(t > slack && t < double(hit.length) - slack)) return frame;
    const Vec3 p{o.x + t * d.x, o.y + t * d.y, o.z + t * d.z};
    const Vec3 outward = SubtractD(p, c);  // the normal, radius long
    // The shadow rays leave the surface where the tracer's do (ray_offset.h).
    const double offset = kRelativeRayOffset * (MaxAbs(o) + t) / s.radius;
    const Vec3 start{p.x + offset * outward.x, p.y + offset * outward.y, p.z + offset * outward.z};
    for (size_t light = 0; light < lights.size(); ++light) {
      if (!LightUnseen(lights[light], p, outward, slack, start, blockers[light], frame)) return frame;
    }
  }
  return before;
}

bool HorizonOracle::LightUnseen(const ShadingLight& light, const Vec3& p, const Vec3& outward, double slack,
                                const Vec3& start, int blocker, int frame) const {
  const Vec3 toward = light.WayFrom(p);
  // Well behind the surface: the cosine between the normal and the way to the light
  // below -2 * slack / radius (compared squared: no root, no division).
  const double along = DotD(outward, toward), length2 = DotD(toward, toward);
  if (along < 0 && along * along > 4 * slack * slack * length2) return true;
  if (blocker < 0 || !(length2 > 0)) return false;
  // Else surely blocked by the sphere that blocked it at frame().
  const bool placed = light.Position() != nullptr;
  const Vec3 shadow = placed ? light.WayFrom(start) : toward;
  const double length = std::sqrt(DotD(shadow, shadow));
  const RaySegment segment{{float(start.x), float(start.y), float(start.z)},
                           {float(shadow.x / length), float(shadow.y / length), float(shadow.z / length)},
                           placed ? float(length) : INFINITY};
  const MovingSphere& b = spheres_[static_cast<size_t>(blocker)];
  const size_t index = static_cast<size_t>(frame - frame_);
  return index < b.centers.size() && TestSureBlock(BlockedRay(segment), b.centers[index], b.radius, b.step).blocked;
}

}  // namespace tcfarm
