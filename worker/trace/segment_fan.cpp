#include "worker/trace/segment_fan.h"

#include <algorithm>
#include <cmath>

namespace tcfarm {
namespace {

// Cone rectangles are widened by this much (face coordinates are at most 1): far above
// the float rounding of the segments' keys, a few parts in 1e7.
constexpr double kConeSlack = 1e-5;

// A face's axis and its two coordinate axes.
struct FaceAxes {
  int axis;
  double sign;
  int uAxis, vAxis;
};
FaceAxes AxesOf(int face) {
  const int axis = face / 2;
  return {axis, face % 2 == 0 ? 1.0 : -1.0, (axis + 1) % 3, (axis + 2) % 3};
}

// The tangents of the angles a disk (centre (across, ahead), radius r) spans as seen from
// the origin, measured from the `ahead` axis; the disk lies wholly ahead (ahead > r).
void TangentRange(double across, double ahead, double r, double* lo, double* hi) {
  const double tangent = std::sqrt(std::max(0.0, across * across + ahead * ahead - r * r));
  *lo = (across * tangent - r * ahead) / (ahead * tangent + r * across);
  *hi = (across * tangent + r * ahead) / (ahead * tangent - r * across);
}

}  // namespace

FaceRect ConeOnFace(int face, const Vec3& center, double radius) {
  const FaceAxes axes = AxesOf(face);
  const double ahead = axes.sign * center[axes.axis];
  const double across[2] = {center[axes.uAxis], center[axes.vAxis]};
  if (ahead < -radius) return {};  // wholly behind the face's plane
  FaceRect rect{-1, 1, -1, 1};
  if (ahead <= radius) return rect;  // reaches the plane: conservatively the whole face
  double* bounds[2][2] = {{&rect.u0, &rect.u1}, {&rect.v0, &rect.v1}};
  for (int i = 0; i < 2; ++i) {
    double lo, hi;
    TangentRange(across[i], ahead, radius, &lo, &hi);
    *bounds[i][0] = std::max(-1.0, lo - kConeSlack * (1 + std::fabs(lo)));
    *bounds[i][1] = std::min(1.0, hi + kConeSlack * (1 + std::fabs(hi)));
  }
  return rect;
}

FanCones::FanCones(const HorizonOracle& oracle, const Vec3& point, double slack)
    : oracle_(oracle), point_(point), slack_(slack), frames_(static_cast<size_t>(oracle.window()) + 1),
      spans_((frames_ - 1 + kSpan - 1) / kSpan) {}

const FaceRect* FanCones::Cones(int face) {
  std::call_once(computed_[face], [&] { Compute(face); });
  return cones_[face].data();
}

const FaceRect* FanCones::SpanCones(int face) {
  std::call_once(computed_[face], [&] { Compute(face); });
  return spanCones_[face].data();
}

void FanCones::Compute(int face) {
  std::vector<FaceRect>& cones = cones_[face];
  std::vector<FaceRect>& spans = spanCones_[face];
  cones.assign(oracle_.MoverCount() * frames_, FaceRect{});
  spans.assign(oracle_.MoverCount() * spans_, FaceRect{});
  for (size_t m = 0; m < oracle_.MoverCount(); ++m) {
    for (size_t f = 1; f < frames_; ++f) {
      const HorizonOracle::MoverSphere proxy = oracle_.MoverAt(m, f);
      if (proxy.radius < 0) continue;
      const Vec3 center{proxy.x - point_.x, proxy.y - point_.y, proxy.z - point_.z};
      // Grown by the slack, and rounded up again for the float radius.
      const double radius = (double(proxy.radius) + slack_) * (1 + 1e-6);
      const FaceRect cone = ConeOnFace(face, center, radius);
      cones[m * frames_ + f] = cone;
      if (cone.Empty()) continue;
      FaceRect& span = spans[m * spans_ + (f - 1) / kSpan];
      if (span.Empty()) {
        span = cone;
      } else {
        span = {std::min(span.u0, cone.u0), std::max(span.u1, cone.u1), std::min(span.v0, cone.v0),
                std::max(span.v1, cone.v1)};
      }
    }
  }
}

bool SegmentFan::Add(uint32_t sample, const RaySegment& segment) {
  // Moved sideways onto the line through the point (by its distance from the point,
  // `apart`), the segment is the set point + s * d for s in [tau, tau + length]. Points
  // with s >= 0 lie in direction d from the point, the others in direction -d. A camera
  // ray leaves the eye (tau = 0): direction d. A shadow ray ends at its light (tau is
  // minus its length, up to rounding): direction -d, but for a stretch past the light
  // of at most `beyond` = tau + length, within that of it. A sphere grown by
  // apart + beyond and still clear of the point therefore meets the segment only in the
  // direction recorded; a sphere that holds the point fills every direction's cone.
  //
  // In float, against half the slack each: direction is unit to float rounding, and
  // rounding here is far below the other half, for points within kFar slacks.
  const Float3 toOrigin = segment.origin - point_;
  const Float3 d = segment.direction;
  if (Dot(toOrigin, toOrigin) > farSquared_) return false;
  const Float3 cross = Cross(toOrigin, d);
  const float tau = Dot(toOrigin, d);
  const bool away = tau >= 0;
  const float beyond = away ? 0.0f : std::max(0.0f, tau + segment.length);
  if (!(Dot(cross, cross) <= halfSlackSquared_ && beyond <= halfSlack_)) return false;
  entries_.push_back({segment, sample});
  keys_.push_back(away ? CubeKeyOf(d.x, d.y, d.z) : CubeKeyOf(-d.x, -d.y, -d.z));
  return true;
}

void SegmentFan::Reset(FanCones* cones) {
  Clear();
  cones_ = cones;
  if (!cones) return;
  const Vec3& p = cones->point();
  point_ = {float(p.x), float(p.y), float(p.z)};
  halfSlack_ = float(cones->slack() / 2);
  halfSlackSquared_ = halfSlack_ * halfSlack_;
  farSquared_ = float(std::pow(kFar * cones->slack(), 2));
}

uint32_t SegmentFan::Grid::Column(double u) const {
  const double c = std::floor((u - u0) * uScale);
  return static_cast<uint32_t>(std::clamp(c, 0.0, double(columns - 1)));
}

uint32_t SegmentFan::Grid::Row(double v) const {
  const double r = std::floor((v - v0) * vScale);
  return static_cast<uint32_t>(std::clamp(r, 0.0, double(rows - 1)));
}

void SegmentFan::Index() {
  std::array<size_t, 6> count{};
  for (Grid& grid : grids_) grid = Grid{};
  for (const CubeKey& key : keys_) {
    Grid& grid = grids_[key.face];
    grid.uMin = std::min(grid.uMin, double(key.u)), grid.uMax = std::max(grid.uMax, double(key.u));
    grid.vMin = std::min(grid.vMin, double(key.v)), grid.vMax = std::max(grid.vMax, double(key.v));
    ++count[key.face];
  }
  faces_.clear();
  uint32_t cells = 0;
  for (int face = 0; face < 6; ++face) {
    Grid& grid = grids_[face];
    grid.firstCell = cells;
    if (count[face] == 0) continue;
    faces_.push_back(face);
    // About four segments a cell, in cells as square as the box allows.
    const double width = std::max(grid.uMax - grid.uMin, 1e-12), height = std::max(grid.vMax - grid.vMin, 1e-12);
    const double cellsWanted = std::max(1.0, double(count[face]) / 4);
    const double side = std::sqrt(width * height / cellsWanted);
    grid.columns = static_cast<uint32_t>(std::clamp(std::ceil(width / side), 1.0, 1024.0));
    grid.rows = static_cast<uint32_t>(std::clamp(std::ceil(height / side), 1.0, 1024.0));
    grid.u0 = grid.uMin, grid.v0 = grid.vMin;
    grid.uScale = grid.columns / width, grid.vScale = grid.rows / height;
    cells += grid.columns * grid.rows;
  }
  // Counting sort by cell.
  cellStart_.assign(size_t{cells} + 1, 0);
  cellOf_.resize(entries_.size());
  for (size_t i = 0; i < entries_.size(); ++i) {
    const Grid& grid = grids_[keys_[i].face];
    cellOf_[i] = grid.firstCell + grid.Row(keys_[i].v) * grid.columns + grid.Column(keys_[i].u);
    ++cellStart_[cellOf_[i] + 1];
  }
  for (size_t c = 1; c < cellStart_.size(); ++c) cellStart_[c] += cellStart_[c - 1];
  sorted_.resize(entries_.size());
  nextInCell_.assign(cellStart_.begin(), cellStart_.end() - 1);
  for (size_t i = 0; i < entries_.size(); ++i) sorted_[nextInCell_[cellOf_[i]]++] = entries_[i];
  entries_.swap(sorted_);
  keys_.clear();
}

void SegmentFan::Clear() {
  entries_.clear();
  keys_.clear();
  faces_.clear();
  cellStart_.clear();
}

}  // namespace tcfarm
