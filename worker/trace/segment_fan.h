// Ray segments that fan out from one point, indexed by their direction from it: a
// pinhole camera's rays leave its eye, and shadow rays toward a point or spot light run
// along lines through the light. Which of them a sphere can meet is then a question of
// directions: those inside the cone the sphere fills as seen from the point. Each cube
// face's directions are laid out on a grid, so that a sphere's cone visits the few cells
// it covers instead of every segment.
//
// Used for validity horizons frame by frame (horizons.h): per frame ahead, each moving
// shape's bounds ask the fan which segments they may meet. A segment's cell is only a
// shortlist: the segment itself is then tested, as a segment tested alone would be.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <mutex>
#include <vector>

#include "proto/scene/scene.h"
#include "worker/trace/float3.h"
#include "worker/trace/horizons.h"

namespace tcfarm {

// Where a direction falls on the cube around the fan's point: face 2 * axis (+ 1 when
// the axis points away), and the direction's other two coordinates divided by its axis
// coordinate, each in [-1, 1].
struct CubeKey {
  int face = 0;
  float u = 0, v = 0;
};
// Inline: asked for every segment a fan records.
inline CubeKey CubeKeyOf(float x, float y, float z) {
  const float ax = std::fabs(x), ay = std::fabs(y), az = std::fabs(z);
  // The axis the direction is most along, and its other two coordinates in the order
  // (axis + 1, axis + 2) mod 3.
  if (ax >= ay && ax >= az) {
    const float inverse = 1.0f / ax;
    return {x < 0 ? 1 : 0, y * inverse, z * inverse};
  }
  if (ay >= az) {
    const float inverse = 1.0f / ay;
    return {y < 0 ? 3 : 2, z * inverse, x * inverse};
  }
  const float inverse = 1.0f / az;
  return {z < 0 ? 5 : 4, x * inverse, y * inverse};
}

// A rectangle of one cube face's coordinates; empty when u0 > u1.
struct FaceRect {
  double u0 = 1, u1 = -1, v0 = 1, v1 = -1;
  bool Empty() const { return u0 > u1 || v0 > v1; }
};
// The directions from the origin toward any point of the sphere (centre relative to the
// fan's point), as a rectangle on `face` that holds them all: the cone's extent along
// each face coordinate, from the sphere seen edge-on in that coordinate's plane.
FaceRect ConeOnFace(int face, const Vec3& center, double radius);

// The cones of every moving shape's bounds at every frame of a horizon oracle's window,
// seen from one point, on each cube face: computed for a face the first time a fan asks
// for it, once per task, since the fans of all the task's chunks share them.
class FanCones {
 public:
  // slack: how far a recorded segment's line may pass from `point` (SegmentFan::Add);
  // every sphere is grown by it.
  FanCones(const HorizonOracle& oracle, const Vec3& point, double slack);
  const Vec3& point() const { return point_; }
  double slack() const { return slack_; }
  // The cones of every mover's bounds on `face`: mover m's at frame offset `offset`
  // (1 .. window) is at [m * Frames() + offset].
  const FaceRect* Cones(int face);
  size_t Frames() const { return frames_; }
  // The union of mover m's cones on `face` over frame offsets [8k + 1, 8k + 8]: one test
  // passes a mover by for eight frames. At [m * Spans() + k].
  static constexpr size_t kSpan = 8;
  const FaceRect* SpanCones(int face);
  size_t Spans() const { return spans_; }

 private:
  const HorizonOracle& oracle_;
  Vec3 point_;
  double slack_;
  size_t frames_;
  size_t spans_;
  std::array<std::once_flag, 6> computed_;
  std::array<std::vector<FaceRect>, 6> cones_;  // [mover * frames_ + offset]
  std::array<std::vector<FaceRect>, 6> spanCones_;  // [mover * spans_ + span]
  void Compute(int face);
};

class SegmentFan {
 public:
  // One segment of sample `sample`'s ray tree: the sample's horizon is what a meeting lowers.
  struct Entry {
    RaySegment segment;
    uint32_t sample;
  };

  SegmentFan() = default;
  explicit SegmentFan(FanCones* cones) { Reset(cones); }
  // Empties the fan and points it at (new) cones; none: the fan takes no segment.
  void Reset(FanCones* cones);
  FanCones* cones() const { return cones_; }
  // Records the segment when its line passes within the cones' slack of the fan's point;
  // false (nothing recorded) otherwise, and the caller tests the segment alone.
  bool Add(uint32_t sample, const RaySegment& segment);
  // Lays the recorded segments out by cell; Add may not be called after it.
  void Index();
  // Whether `rect` on `face` may hold any recorded segment's direction.
  bool Overlaps(int face, const FaceRect& rect) const {
    const Grid& grid = grids_[face];
    return !rect.Empty() && rect.u1 >= grid.uMin && rect.u0 <= grid.uMax && rect.v1 >= grid.vMin &&
           rect.v0 <= grid.vMax;
  }
  // Calls visit(entry) for every recorded segment whose direction lies in `rect` on
  // `face` (and for some beside it).
  template <typename Visit>
  void ForEachIn(int face, const FaceRect& rect, Visit visit) const;
  template <typename Visit>
  void ForEach(Visit visit) const {
    for (const Entry& entry : entries_) visit(entry);
  }
  // Faces that hold segments.
  const std::vector<int>& Faces() const { return faces_; }
  bool empty() const { return entries_.empty(); }
  void Clear();

 private:
  // Per face, a grid over the box of its segments' coordinates.
  struct Grid {
    double u0 = 0, v0 = 0, uScale = 0, vScale = 0;
    uint32_t columns = 1, rows = 1;
    uint32_t firstCell = 0;  // cells of all faces are numbered together
    double uMin = 1, uMax = -1, vMin = 1, vMax = -1;
    uint32_t Column(double u) const;
    uint32_t Row(double v) const;
  };
  // Segments whose origin is farther than this many slacks from the point are left out:
  // Add's float rounding would no longer be negligible against the slack.
  static constexpr double kFar = 1e4;
  FanCones* cones_ = nullptr;
  Float3 point_;
  float halfSlack_ = 0, halfSlackSquared_ = 0, farSquared_ = 0;
  std::vector<Entry> entries_;
  std::vector<CubeKey> keys_;  // of entries_, until Index
  std::vector<uint32_t> cellOf_, nextInCell_;  // Index's scratch, kept for its capacity
  std::vector<Entry> sorted_;
  std::array<Grid, 6> grids_;
  std::vector<int> faces_;
  std::vector<uint32_t> cellStart_;  // entries of cell c: [cellStart_[c], cellStart_[c + 1])
};

template <typename Visit>
void SegmentFan::ForEachIn(int face, const FaceRect& rect, Visit visit) const {
  if (!Overlaps(face, rect)) return;
  const Grid& grid = grids_[face];
  const uint32_t c0 = grid.Column(rect.u0), c1 = grid.Column(rect.u1);
  const uint32_t r0 = grid.Row(rect.v0), r1 = grid.Row(rect.v1);
  for (uint32_t row = r0; row <= r1; ++row) {
    const uint32_t first = grid.firstCell + row * grid.columns;
    for (uint32_t i = cellStart_[first + c0]; i < cellStart_[first + c1 + 1]; ++i) visit(entries_[i]);
  }
}

}  // namespace tcfarm
